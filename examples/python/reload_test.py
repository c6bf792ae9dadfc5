"""A reload test for CI, to copy: edit a DEM the way GDAL (or QGIS) saves
it, wait for reliefd to serve the new generation, and check the new heights
and that the view changed.

Needs the relief package (pip install ./clients/python[test]) and GDAL's
Python bindings; run with `pytest examples/python`. The `relief_client`
and `relief_scene` fixtures come from relief's pytest plugin: an analytic
hill DEM (2000 m at 10.25 E, 45.25 N) with parcels drawn on it, served by
a real reliefd on a free port.
"""

from __future__ import annotations

import numpy as np
import pytest

import relief
from relief.testing import HillScene, raise_window

PEAK = (10.25, 45.25)
# From the south, 45 degrees down: the summit sits in the upper half.
CAMERA = relief.Camera(lon_deg=10.25, lat_deg=45.12, altitude_m=9000, heading_deg=0, pitch_deg=-45)
SIZE = (320, 240)


def test_a_saved_dem_edit_reaches_heights_and_frames(relief_client: relief.Client, relief_scene: HillScene) -> None:
    client = relief_client
    before = client.state()
    assert before.source("dem").status is relief.SourceStatus.READY, before.source("dem").error
    [peak_before] = client.elevation([PEAK])
    assert peak_before is not None, "the summit has data"
    assert peak_before == pytest.approx(relief_scene.height(*PEAK), abs=1.0)
    frame_before = client.render(CAMERA, size=SIZE)

    # The edit: raise 40 x 40 pixels (0.05 degrees) around the summit by
    # 300 m, through GDAL in update mode, then close, as a GIS user's save.
    col, row = relief_scene.pixel(*PEAK)
    raise_window(relief_scene.dem, col - 20, row - 20, 40, 40, by_m=300.0)

    after = client.wait_for_generation(before.generation + 1, timeout=30)
    assert after.source("dem").version > before.source("dem").version
    [peak_after, plain] = client.elevation([PEAK, (10.02, 45.02)])
    assert peak_after == pytest.approx(peak_before + 300.0, abs=1.0)
    assert plain == pytest.approx(relief_scene.height(10.02, 45.02), abs=1.0), "outside the window nothing moved"

    frame_after = client.render(CAMERA, size=SIZE)
    assert frame_after.generation >= after.generation
    changed = np.any(frame_after.to_numpy() != frame_before.to_numpy(), axis=2)
    assert changed.mean() > 0.001, "the raised summit shows in the view"
