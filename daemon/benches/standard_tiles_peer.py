"""The peer side of `cargo bench -p relief-daemon --bench standard_tiles`:
the same height tiles meshed by pydelatin (Delatin, greedy insertion to a
max error) and encoded by quantized-mesh-encoder, with vertex normals as
relief encodes them.

    python standard_tiles_peer.py TILES.json

TILES.json (written by the bench): {"size": 257, "errors_m": [...],
"passes": 3, "tiles": [{"path": "...f32", "bounds": [west, south, east,
north]}, ...]}; each file holds size x size little-endian f32 heights,
rows from the north (relief's filled heights, `Rtin::heights`). Prints one
JSON line per error: the seconds of each pass over every tile (mesh +
encode, the files already read), bytes and gzip bytes (level 6, flate2's
default, as relief's `gzip`), triangles and Delatin's own max error, summed
or maxed over the tiles.
"""

from __future__ import annotations

import gzip
import io
import json
import sys
import time

import numpy as np
from pydelatin import Delatin
from pydelatin.util import rescale_positions
from quantized_mesh_encoder import WGS84, VertexNormalsExtension, encode


def mesh_and_encode(heights: np.ndarray, bounds: list[float], max_error: float) -> tuple[bytes, int, float]:
    size = heights.shape[0]
    tin = Delatin(heights, width=size, height=size, max_error=max_error)
    # Row 0 is the north edge: flip y so it lands on `north`.
    positions = rescale_positions(tin.vertices, bounds, flip_y=True)
    triangles = tin.triangles
    out = io.BytesIO()
    normals = VertexNormalsExtension(indices=triangles, positions=positions, ellipsoid=WGS84)
    encode(out, positions, triangles, bounds=bounds, ellipsoid=WGS84, extensions=[normals])
    return out.getvalue(), len(triangles), float(tin.error)


def main() -> None:
    with open(sys.argv[1], encoding="utf-8") as f:
        spec = json.load(f)
    size = spec["size"]
    tiles = [
        (np.fromfile(t["path"], dtype="<f4").reshape(size, size), [float(b) for b in t["bounds"]]) for t in spec["tiles"]
    ]
    for max_error in spec["errors_m"]:
        seconds = []
        for _ in range(spec["passes"]):
            start = time.perf_counter()
            for heights, bounds in tiles:
                mesh_and_encode(heights, bounds, max_error)
            seconds.append(time.perf_counter() - start)
        total_bytes = total_gzip = triangles = 0
        worst = 0.0
        for heights, bounds in tiles:
            data, count, error = mesh_and_encode(heights, bounds, max_error)
            total_bytes += len(data)
            total_gzip += len(gzip.compress(data, compresslevel=6))
            triangles += count
            worst = max(worst, error)
        line = {
            "error_m": max_error,
            "seconds": seconds,
            "tiles": len(tiles),
            "bytes": total_bytes,
            "gzip_bytes": total_gzip,
            "triangles": triangles,
            "max_error_m": worst,
        }
        print(json.dumps(line), flush=True)


if __name__ == "__main__":
    main()
