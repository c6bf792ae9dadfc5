"""Drives a real QGIS, headless, editing one layer of a GeoPackage: relief's
tests and benchmarks use it to make the commits an analyst makes.

    QT_QPA_PLATFORM=offscreen /usr/bin/python3 qgis_editor.py FILE.gpkg LAYER [ALSO ...]

ALSO: more layers of the same file to keep loaded (QGIS then keeps the file
in WAL mode). Speaks JSON lines: first {"ready": true, "features": [...]};
then, for each command line read,
  {"edits": [EDIT, ...], "stay_editing": false}  ->  {"t0", "t1", "features"}
  {"quit": true}
where EDIT is one of
  {"kind": "move_vertex", "fid": F, "vertex": V, "dx": DX, "dy": DY}
  {"kind": "add", "wkt": WKT, "attrs": {NAME: VALUE}}
  {"kind": "delete", "fid": F}
  {"kind": "set", "fid": F, "field": NAME, "value": VALUE}
t0 and t1 are the wall clock (seconds) just before and after commitChanges;
features are the layer as QGIS reads it back after the commit:
{"fid", "attrs", "coords": [[x, y], ...]} sorted by fid. An error is
{"error": "..."}."""

import json
import sys
import time

from qgis.core import QgsApplication, QgsFeature, QgsGeometry, QgsVectorLayer


def reply(message):
    print(json.dumps(message), flush=True)


def value(v):
    """A QGIS attribute as JSON (NULL, a QVariant, becomes null)."""
    if v is None or (hasattr(v, "isNull") and v.isNull()):
        return None
    return v if isinstance(v, (int, float, str, bool)) else str(v)


def features(layer):
    out = []
    for f in layer.getFeatures():
        g = f.geometry()
        coords = [] if g.isNull() else [[p.x(), p.y()] for p in g.vertices()]
        attrs = {field.name(): value(f[field.name()]) for field in layer.fields() if field.name() != "fid"}
        out.append({"fid": f.id(), "attrs": attrs, "coords": coords})
    return sorted(out, key=lambda f: f["fid"])


def edit(layer, e):
    kind = e["kind"]
    if kind == "move_vertex":
        v = layer.getFeature(e["fid"]).geometry().vertexAt(e["vertex"])
        return layer.moveVertex(v.x() + e["dx"], v.y() + e["dy"], e["fid"], e["vertex"])
    if kind == "add":
        f = QgsFeature(layer.fields())
        for name, v in e.get("attrs", {}).items():
            f[name] = v
        f.setGeometry(QgsGeometry.fromWkt(e["wkt"]))
        return layer.addFeature(f)
    if kind == "delete":
        return layer.deleteFeature(e["fid"])
    if kind == "set":
        return layer.changeAttributeValue(e["fid"], layer.fields().indexOf(e["field"]), e["value"])
    raise ValueError(f"no such edit: {kind}")


def main():
    path, name, *also = sys.argv[1:]
    QgsApplication.setPrefixPath("/usr", True)
    app = QgsApplication([], False)
    app.initQgis()
    layer = QgsVectorLayer(f"{path}|layername={name}", name, "ogr")
    others = [QgsVectorLayer(f"{path}|layername={o}", o, "ogr") for o in also]
    if not layer.isValid() or not all(o.isValid() for o in others):
        reply({"error": f"QGIS cannot load the layers of {path}"})
        return 1
    reply({"ready": True, "features": features(layer)})
    for line in sys.stdin:
        command = json.loads(line)
        if command.get("quit"):
            break
        layer.startEditing()
        failed = [e for e in command["edits"] if not edit(layer, e)]
        if failed:
            layer.rollBack()
            reply({"error": f"QGIS refused the edits {failed}"})
            continue
        t0 = time.time()
        ok = layer.commitChanges(not command.get("stay_editing", False))
        t1 = time.time()
        if not ok:
            reply({"error": "; ".join(layer.commitErrors())})
            continue
        reply({"t0": t0, "t1": t1, "features": features(layer)})
    del layer, others
    app.exitQgis()
    return 0


if __name__ == "__main__":
    sys.exit(main())
