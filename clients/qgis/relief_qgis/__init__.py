"""relief for QGIS: reliefd's live 3D view in a dock, following the map.

QGIS loads this package and calls classFactory(iface). It uses only QGIS
and the Qt QGIS ships (through qgis.PyQt), nothing installed with pip."""


def classFactory(iface):  # noqa: N802 (QGIS's name)
    from .plugin import ReliefPlugin

    return ReliefPlugin(iface)
