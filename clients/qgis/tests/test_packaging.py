"""The zip against what the QGIS plugin repository (plugins.qgis.org) asks
of a plugin's metadata.txt: the required fields, the recommended ones,
values of the right kind, and the files they name inside the zip."""

from __future__ import annotations

import configparser
import re
import zipfile

import pytest
from conftest import PLUGIN, PLUGIN_ZIP

#: Required by the plugin repository (QGIS's PyQGIS cookbook, "Plugin metadata").
REQUIRED = ("name", "qgisMinimumVersion", "description", "about", "version", "author", "email", "repository")
#: Recommended there; this plugin gives them all.
RECOMMENDED = ("tracker", "homepage", "tags", "category", "icon", "experimental", "deprecated", "changelog")
#: The menus a plugin's category may name.
CATEGORIES = {"Plugins", "Raster", "Vector", "Database", "Mesh", "Web"}
URL = re.compile(r"^https?://[^\s/]+\.[^\s/]+(/\S*)?$")


@pytest.fixture(scope="module")
def metadata() -> configparser.SectionProxy:
    with zipfile.ZipFile(PLUGIN_ZIP) as z:
        text = z.read(f"{PLUGIN}/metadata.txt").decode("utf-8")
    # As QGIS reads it (qgis.utils.metadataParser): an ini file, keys as written.
    parser = configparser.ConfigParser(interpolation=None)
    parser.optionxform = str  # type: ignore[assignment,method-assign]
    parser.read_string(text)
    return parser["general"]


@pytest.mark.parametrize("field", REQUIRED + RECOMMENDED)
def test_each_field_the_repository_asks_for_is_given(metadata: configparser.SectionProxy, field: str) -> None:
    assert metadata.get(field, "").strip(), f"metadata.txt has no {field}"


def test_the_values_are_of_their_kind(metadata: configparser.SectionProxy) -> None:
    assert re.fullmatch(r"\d+\.\d+\.\d+", metadata["version"]), metadata["version"]
    assert metadata["qgisMinimumVersion"] == "3.22"
    assert re.fullmatch(r"[^@\s]+@[^@\s]+\.[^@\s]+", metadata["email"]), metadata["email"]
    for field in ("repository", "tracker", "homepage"):
        assert URL.match(metadata[field]), (field, metadata[field])
    assert metadata["category"] in CATEGORIES, metadata["category"]
    for field in ("experimental", "deprecated"):
        assert metadata[field] in ("True", "False"), (field, metadata[field])
    assert metadata["deprecated"] == "False"
    assert len(metadata["description"]) <= 200 and "\n" not in metadata["description"]
    assert len(metadata["about"]) > len(metadata["description"])
    tags = [t.strip() for t in metadata["tags"].split(",")]
    assert all(tags) and len(tags) == len(set(tags)), tags


def test_the_files_it_names_are_in_the_zip_with_the_licence(metadata: configparser.SectionProxy) -> None:
    with zipfile.ZipFile(PLUGIN_ZIP) as z:
        names = set(z.namelist())
        assert f"{PLUGIN}/{metadata['icon']}" in names
        assert f"{PLUGIN}/LICENSE" in names, "the plugin repository wants a LICENSE in the zip"
        assert "Apache License" in z.read(f"{PLUGIN}/LICENSE").decode("utf-8")
    assert metadata["license"] == "Apache-2.0"


def test_qgis_reads_the_metadata_of_the_installed_plugin() -> None:
    import qgis.utils
    from headless import PLUGINS_DIR

    qgis.utils.plugin_paths = [str(PLUGINS_DIR)]
    qgis.utils.updateAvailablePlugins()
    assert PLUGIN in qgis.utils.available_plugins
    assert qgis.utils.pluginMetadata(PLUGIN, "name") == "relief 3D view"
    assert qgis.utils.pluginMetadata(PLUGIN, "repository").startswith("https://")
    assert "@" in qgis.utils.pluginMetadata(PLUGIN, "email")
