"""xDEM timings for `terrafuse bench compare`: on two rasters in one projected CRS (the second
reprojected onto the first's grid when they differ), the
statistics of dh (numpy and xdem.spatialstats.nmad) and Nuth & Kääb. Prints JSON:
{"stats_s", "coreg_s", "count", "nmad_m", "shift_x", "shift_y", "shift_z"}.
"""
import json
import sys
import time
import warnings

warnings.filterwarnings("ignore")
import numpy as np  # noqa: E402
import xdem  # noqa: E402

start = time.time()
reference = xdem.DEM(sys.argv[1])
to_align = xdem.DEM(sys.argv[2])
if to_align.shape != reference.shape or to_align.transform != reference.transform:
    to_align = to_align.reproject(reference)  # onto the reference's grid, as xDEM's guides do
dh = (to_align - reference).data.compressed().astype(float)
stats = {
    "mean": float(np.mean(dh)), "median": float(np.median(dh)), "std": float(np.std(dh)),
    "rmse": float(np.sqrt(np.mean(dh**2))), "nmad": float(xdem.spatialstats.nmad(dh)),
    "le90": float(np.percentile(dh, 95) - np.percentile(dh, 5)),
}
stats_s = time.time() - start
start = time.time()
coreg = xdem.coreg.NuthKaab()
coreg.fit(reference, to_align)
matrix = coreg.to_matrix()
print(json.dumps({
    "stats_s": stats_s, "coreg_s": time.time() - start, "count": int(dh.size), "nmad_m": stats["nmad"],
    "shift_x": float(matrix[0, 3]), "shift_y": float(matrix[1, 3]), "shift_z": float(matrix[2, 3]),
}))
