"""xDEM's and gdaldem's terrain attributes of a heights GeoTIFF against Terrafuse's, for
tests/attributes.rs.

usage: terrain_attributes.py HEIGHTS.tif DIR NAME…

For each NAME, DIR/NAME.tif is Terrafuse's attribute of the same grid. Prints JSON: per name,
{"xdem": [max |d|, 99th percentile |d|, pixels], "gdal": [...]} over the pixels both have, two
pixels in from the edges, with "slope_deg" (the slope there, for tolerances that grow with it)
absent; "gdal" only where gdaldem has the attribute. xDEM: surface_fit "Horn" for slope, aspect
and hillshade, "ZevenbergThorne" for the curvatures, TRI by Riley; gdaldem: slope, aspect,
hillshade (byte, 315°, 45°), TRI -alg Riley, TPI, roughness.
"""
import json
import os
import subprocess
import sys
import tempfile
import warnings

warnings.filterwarnings("ignore")
import numpy as np  # noqa: E402
import rasterio  # noqa: E402
import xdem  # noqa: E402

heights_path, folder, names = sys.argv[1], sys.argv[2], sys.argv[3:]


def read(path):
    with rasterio.open(path) as d:
        a = d.read(1).astype(np.float64)
        if d.nodata is not None and not np.isnan(d.nodata):
            a[a == d.nodata] = np.nan
        return a


dem = xdem.DEM(heights_path)
slope = np.ma.filled(xdem.terrain.slope(dem, surface_fit="Horn").data, np.nan).astype(np.float64)
gdal_names = {
    "slope": ["slope"],
    "aspect": ["aspect"],
    "hillshade": ["hillshade"],
    "tri": ["TRI", "-alg", "Riley"],
    "tpi": ["TPI"],
    "roughness": ["roughness"],
}
out = {}
tmp = tempfile.mkdtemp()
for name in names:
    ours = read(os.path.join(folder, f"{name}.tif"))
    fit = "ZevenbergThorne" if "curvature" in name else "Horn"
    kwargs = {"surface_fit": fit} if name in ("slope", "aspect", "hillshade") or "curvature" in name else {}
    xdem_name = {"tpi": "topographic_position_index", "tri": "terrain_ruggedness_index"}.get(name, name)
    theirs = np.ma.filled(xdem.terrain.get_terrain_attribute(dem, attribute=xdem_name, **kwargs).data, np.nan)
    result = {}

    def compare(theirs, circular=False):
        keep = np.isfinite(ours) & np.isfinite(theirs)
        keep[:2, :] = keep[-2:, :] = keep[:, :2] = keep[:, -2:] = False
        d = ours[keep] - theirs[keep]
        if circular:
            d = (d + 180.0) % 360.0 - 180.0
        if name == "aspect":
            # Aspect is undefined on the flat: compared where the slope passes 5°.
            d = d[slope[keep] > 5.0]
        d = np.abs(d)
        return [float(d.max()), float(np.percentile(d, 99)), int(d.size)]

    result["xdem"] = compare(theirs.astype(np.float64), circular=name == "aspect")
    if name in gdal_names:
        path = os.path.join(tmp, f"{name}.tif")
        subprocess.run(["gdaldem", *gdal_names[name], heights_path, path, "-q"], check=True)
        g = read(path)
        if name == "hillshade":
            g[g == 0] = np.nan
        g[g == -9999] = np.nan
        result["gdal"] = compare(g, circular=name == "aspect")
    out[name] = result
print(json.dumps(out))
