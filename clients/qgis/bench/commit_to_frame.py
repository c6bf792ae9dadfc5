"""Benchmark: a QGIS commit to a new frame in the plugin's dock.

Headless QGIS (offscreen Qt) with the plugin installed from its zip, a real
reliefd serving relief.testing's hill scene, and the scene's parcels
shapefile open as a QGIS layer. Each round moves a vertex of a parcel
(there and back, 0.005 degrees) and commits, as an analyst saving an edit
does; the clock starts just before commitChanges() and stops when the dock
shows a frame of a newer generation. The same rounds also time the commit
to the plugin learning of the new generation (its /api/events stream),
which is what "a commit becomes a new generation" measures, and the frame
after it (drawing and pushing the PNG). The rounds run twice: with the
plugin asking for a reload on commit (what it does), then with the file
watcher alone taking the save (the peer: relief before the plugin), and
the table ends with their ratio.

    clients/qgis/scripts/bench.sh [--commits N] [--size WxH]

Prints the machine and a table (milliseconds)."""

from __future__ import annotations

import argparse
import os
import platform
import statistics
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))
import headless  # noqa: E402  (makes the QgsApplication)
from relief_qgis import proto_json as pj  # noqa: E402  (the installed copy, on sys.path once headless runs)
from qgis.core import QgsProject, QgsVectorLayer  # noqa: E402

from relief.testing import Reliefd, write_hill_scene  # noqa: E402

def percentile(values: list[float], q: float) -> float:
    ordered = sorted(values)
    k = (len(ordered) - 1) * q
    lo, hi = int(k), min(int(k) + 1, len(ordered) - 1)
    return ordered[lo] + (ordered[hi] - ordered[lo]) * (k - lo)

def cpu() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown CPU"

def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--commits", type=int, default=30, help="commits to time (at least 20)")
    parser.add_argument("--size", default="640x360", help="the dock's frame size, WxH")
    args = parser.parse_args()
    width, height = (int(v) for v in args.size.lower().split("x"))

    import tempfile

    with tempfile.TemporaryDirectory(prefix="relief-qgis-bench-") as folder:
        scene = write_hill_scene(Path(folder) / "scene")
        with Reliefd(scene.manifest) as daemon:
            host = headless.Host()
            plugin = headless.start_plugin(host, daemon.address)
            link, dock = plugin.link, plugin.dock
            # A fixed frame size, whatever the window's layout gives the dock.
            dock.frame_size_changed.disconnect()
            link.set_frame_size(width, height)
            if not headless.wait_for(lambda: dock.frames_shown > 0, 60):
                print("no frame reached the dock within 60 s", file=sys.stderr)
                return 1

            layer = QgsVectorLayer(str(scene.parcels), "parcels", "ogr")
            QgsProject.instance().addMapLayer(layer)
            feature = next(layer.getFeatures())

            seen: dict[str, float] = {}
            link.state.connect(lambda s: seen.setdefault(f"state{pj.integer(s, 'generation')}", time.perf_counter()))
            link.frame.connect(lambda _i, g, _c: seen.setdefault(f"frame{g}", time.perf_counter()))

            def rounds(n: int) -> tuple[list[float], list[float], int]:
                to_generation, to_frame, late = [], [], 0
                for i in range(n):
                    # Let the last round's frames settle so each round starts idle.
                    headless.wait_for(lambda: False, 0.3)
                    before = dock.frame_generation
                    step = 0.005 if i % 2 == 0 else -0.005
                    layer.startEditing()
                    vertex = layer.getFeature(feature.id()).geometry().vertexAt(0)
                    layer.moveVertex(vertex.x() + step, vertex.y() + step, feature.id(), 0)
                    seen.clear()
                    start = time.perf_counter()
                    if not layer.commitChanges():
                        raise RuntimeError(f"commit {i} failed: {layer.commitErrors()}")
                    shown = headless.wait_for(lambda: dock.frame_generation > before and dock.frame_generation, 30)
                    if not shown:
                        late += 1
                        continue
                    to_frame.append(1000 * (seen[f"frame{shown}"] - start))
                    states = [t for k, t in seen.items() if k.startswith("state") and int(k[5:]) > before]
                    if states:
                        to_generation.append(1000 * (min(states) - start))
                return to_generation, to_frame, late

            results = {}
            for reload_on_commit in (True, False):
                plugin.reload_on_commit = reload_on_commit
                results[reload_on_commit] = rounds(args.commits)
            size = "{}x{}".format(*link.frame_size)
            headless.stop_plugin()
            host.close()

    print(f"machine: {cpu()}, {os.cpu_count()} cores; QGIS {headless.qgis_version()}; reliefd {daemon.binary}")
    print(f"frames: {size} PNG, renderer as reliefd found it (lavapipe without a GPU)")
    print(f"{'QGIS commit to ...':<52}{'n':>4}{'p50':>9}{'p95':>9}{'min':>9}{'max':>9}   (ms)")
    late = 0
    for reload_on_commit, how, short in (
        (True, "the plugin asks for a reload", "reload on commit"),
        (False, "the file watcher alone", "watcher alone"),
    ):
        to_generation, to_frame, missed = results[reload_on_commit]
        late += missed
        for name, values in (("the plugin hears the new generation", to_generation), ("a new frame in the dock", to_frame)):
            if values:
                label = f"{name} ({short})"
                print(
                    f"{label:<52}{len(values):>4}{statistics.median(values):>9.1f}"
                    f"{percentile(values, 0.95):>9.1f}{min(values):>9.1f}{max(values):>9.1f}"
                )
        if missed:
            print(f"{missed} commit(s) with {how} showed no new frame within 30 s")
    fast, slow = results[True][1], results[False][1]
    if fast and slow:
        print(
            f"commit to frame, plugin reload / watcher alone: p50 {statistics.median(fast) / statistics.median(slow):.2f}x,"
            f" p95 {percentile(fast, 0.95) / percentile(slow, 0.95):.2f}x"
        )
    return 0 if min(len(fast), len(slow)) >= 20 and not late else 1

if __name__ == "__main__":
    sys.exit(main())
