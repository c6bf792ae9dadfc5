"""An ArcGIS-like editor of a file geodatabase for relief's tests: GDAL's
OpenFileGDB driver (Debian's python3-gdal), driven by one JSON command a
line on stdin, one JSON reply a line on stdout.

Each edit opens the geodatabase in update mode, makes its change and
closes it (what GDAL writes on close is the save), then replies with the
time the save was done (`t`, seconds since the epoch). Commands:

  {"create": [layer, ...]}  layer: {"name", "geom": "polygon" | "point" |
                            "multipatch", "fields": [name, ...],
                            "features": [{"wkt", "attrs": {...}}, ...]}
  {"update": layer, "fid": n, "attrs": {...}, "wkt": optional}
  {"insert": layer, "wkt": ..., "attrs": {...}}      replies {"fid"}
  {"delete": layer, "fid": n}
  {"move": layer, "count": n, "dx": x, "dy": y}      the first n features
  {"repack": layer}                                  SQL REPACK
  {"read": layer}                                    replies {"features": [...]}
  {"quit": true}
"""

import json
import sys
import time

from osgeo import gdal, ogr, osr

gdal.UseExceptions()

GEOMS = {
    "polygon": ogr.wkbPolygon,
    "point": ogr.wkbPoint,
    # OpenFileGDB makes a MultiPatch table of a geometry-collection layer.
    "multipatch": ogr.wkbGeometryCollection25D,
}


def open_update(path):
    return gdal.OpenEx(path, gdal.OF_VECTOR | gdal.OF_UPDATE, allowed_drivers=["OpenFileGDB"])


def create(path, layers):
    srs = osr.SpatialReference()
    srs.ImportFromEPSG(4326)
    srs.SetAxisMappingStrategy(osr.OAMS_TRADITIONAL_GIS_ORDER)
    ds = ogr.GetDriverByName("OpenFileGDB").CreateDataSource(path)
    for spec in layers:
        layer = ds.CreateLayer(spec["name"], srs, GEOMS[spec["geom"]])
        for name in spec.get("fields", []):
            layer.CreateField(ogr.FieldDefn(name, ogr.OFTString))
        layer.StartTransaction()
        for f in spec.get("features", []):
            add(layer, f["wkt"], f.get("attrs", {}))
        layer.CommitTransaction()
    ds = None


def add(layer, wkt, attrs):
    feature = ogr.Feature(layer.GetLayerDefn())
    feature.SetGeometry(ogr.CreateGeometryFromWkt(wkt))
    for k, v in attrs.items():
        feature.SetField(k, v)
    layer.CreateFeature(feature)
    return feature.GetFID()


def shift(g, dx, dy):
    """Moves every point of `g`, at any depth (OpenFileGDB gives polygons
    as multipolygons)."""
    for i in range(g.GetGeometryCount()):
        shift(g.GetGeometryRef(i), dx, dy)
    for i in range(g.GetPointCount()):
        g.SetPoint_2D(i, g.GetX(i) + dx, g.GetY(i) + dy)


def read(layer):
    return [
        {
            "fid": f.GetFID(),
            "wkt": f.GetGeometryRef().ExportToIsoWkt() if f.GetGeometryRef() else None,
            "attrs": {k: v for k, v in f.items().items() if v is not None},
        }
        for f in layer
    ]


def run(path, command):
    if "create" in command:
        create(path, command["create"])
        return {}
    ds = open_update(path)
    reply = {}
    if "update" in command:
        layer = ds.GetLayerByName(command["update"])
        feature = layer.GetFeature(command["fid"])
        for k, v in command.get("attrs", {}).items():
            feature.SetField(k, v)
        if "wkt" in command:
            feature.SetGeometry(ogr.CreateGeometryFromWkt(command["wkt"]))
        layer.SetFeature(feature)
    elif "insert" in command:
        layer = ds.GetLayerByName(command["insert"])
        reply["fid"] = add(layer, command["wkt"], command.get("attrs", {}))
    elif "delete" in command:
        ds.GetLayerByName(command["delete"]).DeleteFeature(command["fid"])
    elif "move" in command:
        layer = ds.GetLayerByName(command["move"])
        layer.StartTransaction()
        moved = [f for _, f in zip(range(command["count"]), layer)]
        for f in moved:
            g = f.GetGeometryRef()
            shift(g, command["dx"], command["dy"])
            f.SetGeometry(g)
            layer.SetFeature(f)
        layer.CommitTransaction()
        reply["moved"] = len(moved)
    elif "repack" in command:
        ds.ExecuteSQL("REPACK " + command["repack"])
    elif "read" in command:
        reply["features"] = read(ds.GetLayerByName(command["read"]))
    ds = None
    reply["t"] = time.time()
    return reply


def main():
    path = sys.argv[1]
    print(json.dumps({"ready": True, "gdal": gdal.__version__}), flush=True)
    for line in sys.stdin:
        command = json.loads(line)
        if command.get("quit"):
            break
        try:
            reply = run(path, command)
        except Exception as e:  # the test shows it
            reply = {"error": str(e)}
        print(json.dumps(reply), flush=True)


if __name__ == "__main__":
    main()
