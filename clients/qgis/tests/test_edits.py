"""Which scene sources a committed layer's file belongs to."""

from __future__ import annotations

from pathlib import Path

from conftest import PLUGIN  # noqa: F401 (the plugin's folder is on sys.path)
from qgis.core import QgsVectorLayer
from relief_qgis.edits import layer_file, sources_reading

from relief.testing import write_polygons


def state_for(folder: Path) -> dict:
    return {
        "sources": [
            {"id": "dem", "files": [str(folder / "hill.tif")]},
            {"id": "parcels", "files": [str(folder / "parcels.shp"), str(folder / "parcels.dbf")]},
            {"id": "roads", "files": [str(folder / "roads.gpkg")]},
            {"id": "shade"},
        ]
    }


def test_a_shapefile_part_names_its_source(tmp_path: Path) -> None:
    state = state_for(tmp_path)
    for part in ("parcels.shp", "parcels.dbf", "parcels.shx", "parcels.SHP"):
        assert sources_reading(state, str(tmp_path / part)) == ["parcels"], part
    assert sources_reading(state, str(tmp_path / "roads.gpkg")) == ["roads"]
    assert sources_reading(state, str(tmp_path / "other.shp")) == []
    assert sources_reading({}, str(tmp_path / "parcels.shp")) == []


def test_a_path_through_a_link_is_the_same_file(tmp_path: Path) -> None:
    (tmp_path / "real").mkdir()
    (tmp_path / "link").symlink_to(tmp_path / "real")
    state = state_for(tmp_path / "real")
    assert sources_reading(state, str(tmp_path / "link" / "parcels.shp")) == ["parcels"]


def test_the_file_of_a_layer(tmp_path: Path) -> None:
    path = write_polygons(tmp_path / "parcels.shp")
    layer = QgsVectorLayer(f"{path}|layername=parcels", "parcels", "ogr")
    assert layer.isValid()
    assert layer_file(layer) == str(path.resolve())
    memory = QgsVectorLayer("Point?crs=EPSG:4326", "scratch", "memory")
    assert layer_file(memory) is None
