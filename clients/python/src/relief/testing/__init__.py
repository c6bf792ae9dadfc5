"""Testing with a real reliefd: a pytest plugin (fixtures `relief_scene`,
`reliefd_args`, `reliefd`, `relief_token`, `relief_client`), the hill scene
it serves, edits of GIS files made the way GIS tools make them, and a token
file and TLS certificates for a reliefd off loopback.

    def test_reload(relief_client, relief_scene):
        generation = relief_client.state().generation
        col, row = relief_scene.pixel(10.25, 45.25)
        raise_window(relief_scene.dem, col - 20, row - 20, 40, 40, by_m=300.0)
        relief_client.wait_for_generation(generation + 1, timeout=30)
        assert relief_client.elevation([(10.25, 45.25)])[0] > 2200
"""

from relief.testing.daemon import BIN_ENV, Reliefd, find_reliefd
from relief.testing.edits import (
    add_feature,
    edit_window,
    feature_count,
    move_vertex,
    pixel_of,
    raise_window,
    read_window,
    set_attribute,
    write_window,
)
from relief.testing.security import (
    CONTROL_TOKEN,
    READ_TOKEN,
    Certificates,
    TokenFile,
    make_certificates,
    write_token_file,
)
from relief.testing.scene import (
    PARCELS,
    HillScene,
    hill,
    hill_at,
    hill_pixels,
    write_hill_dem,
    write_hill_scene,
    write_polygons,
)

__all__ = [
    "BIN_ENV",
    "CONTROL_TOKEN",
    "Certificates",
    "PARCELS",
    "READ_TOKEN",
    "TokenFile",
    "HillScene",
    "Reliefd",
    "add_feature",
    "edit_window",
    "feature_count",
    "find_reliefd",
    "make_certificates",
    "hill",
    "hill_at",
    "hill_pixels",
    "move_vertex",
    "pixel_of",
    "raise_window",
    "read_window",
    "set_attribute",
    "write_hill_dem",
    "write_hill_scene",
    "write_polygons",
    "write_token_file",
    "write_window",
]
