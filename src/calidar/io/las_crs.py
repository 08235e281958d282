"""The CRS of a LAS/LAZ header: the WKT VLR, else the GeoTIFF keys (including the user-defined
projected CRSs and the geocentric model type laspy does not resolve)."""

from __future__ import annotations

import laspy
import pyproj


def _geokey_crs(header: laspy.LasHeader) -> pyproj.CRS | None:
    """CRS of GeoTIFF keys laspy does not resolve: a user-defined projected CRS given by an EPSG
    projection (conversion) code, e.g. UTM zone 11N = 16011, on an EPSG or WGS 84-parameter
    datum."""
    keys = doubles = None
    for v in header.vlrs:
        if isinstance(v, laspy.vlrs.known.GeoKeyDirectoryVlr):
            keys = {k.id: k for k in v.geo_keys}
        elif isinstance(v, laspy.vlrs.known.GeoDoubleParamsVlr):
            doubles = [float(d.value) if hasattr(d, "value") else float(d) for d in v.doubles]
    if not keys or 3074 not in keys or keys[3074].tiff_tag_location != 0:
        return None

    def value(key_id):
        k = keys.get(key_id)
        if k is None:
            return None
        if k.tiff_tag_location == 0:
            return k.value_offset
        if k.tiff_tag_location == 34736 and doubles is not None and k.value_offset < len(doubles):
            return doubles[k.value_offset]
        return None

    geographic = value(2048)
    if geographic is not None and 1024 <= geographic <= 32766:
        geodetic = pyproj.CRS.from_epsg(int(geographic))
    else:
        a, rf = value(2057), value(2059)
        if a is None or rf is None:
            return None
        if abs(a - 6378137.0) < 1e-3 and abs(rf - 298.257223563) < 1e-6:
            geodetic = pyproj.CRS.from_epsg(4326)
        else:
            geodetic = pyproj.CRS.from_proj4(f"+proj=longlat +a={a} +rf={rf} +no_defs")
    try:
        conversion = pyproj.crs.CoordinateOperation.from_epsg(int(keys[3074].value_offset))
        crs = pyproj.crs.ProjectedCRS(conversion=conversion, geodetic_crs=geodetic)
    except pyproj.exceptions.CRSError:
        return None
    epsg = crs.to_epsg(min_confidence=70)
    return pyproj.CRS.from_epsg(epsg) if epsg else crs


def _geocentric(crs: pyproj.CRS) -> pyproj.CRS:
    """The geocentric (ECEF) CRS on the datum of a geographic CRS (WGS 84 → EPSG:4978)."""
    d = crs.to_json_dict()
    d.pop("id", None)
    d["type"] = "GeodeticCRS"
    d["coordinate_system"] = pyproj.CRS.from_epsg(4978).to_json_dict()["coordinate_system"]
    geo = pyproj.CRS.from_json_dict(d)
    epsg = geo.to_epsg(min_confidence=70)
    return pyproj.CRS.from_epsg(epsg) if epsg else geo


def _model_type(header: laspy.LasHeader) -> int | None:
    """GTModelTypeGeoKey (1024) of the GeoTIFF keys: 1 projected, 2 geographic, 3 geocentric."""
    for v in header.vlrs:
        if isinstance(v, laspy.vlrs.known.GeoKeyDirectoryVlr):
            for k in v.geo_keys:
                if k.id == 1024 and k.tiff_tag_location == 0:
                    return int(k.value_offset)
    return None


def las_crs(header: laspy.LasHeader) -> pyproj.CRS | None:
    """The CRS of a LAS header (WKT VLR preferred, then GeoTIFF keys), or None.

    GeoTIFF keys with model type geocentric (1024 = 3) mean ECEF on the datum of the
    GeographicTypeGeoKey; laspy returns that geographic CRS, which would read ECEF metres as
    degrees.
    """
    try:
        crs = header.parse_crs()
    except pyproj.exceptions.CRSError:
        crs = None
    crs = crs if crs is not None else _geokey_crs(header)
    if crs is not None and crs.is_geographic and _model_type(header) == 3:
        return _geocentric(crs)
    return crs
