"""xDEM's statistics of dh = A − B for `BENCHMARKS.md`'s comparison at 10⁸ samples: two rasters on
one grid, read as xdem.DEM, differenced, and the statistics `terrafuse compare` prints (numpy's
mean, median, std, RMSE, percentiles; xdem.spatialstats.nmad), as xDEM's guides compute them.
Prints JSON: {"seconds", "count", "mean_m", "median_m", "nmad_m", "le90_m"}; run it under
`/usr/bin/time -v` for the peak memory.
"""
import json
import sys
import time
import warnings

warnings.filterwarnings("ignore")
import numpy as np  # noqa: E402
import xdem  # noqa: E402

start = time.time()
a = xdem.DEM(sys.argv[1])
b = xdem.DEM(sys.argv[2])
dh = (a - b).data.compressed().astype(float)
print(json.dumps({
    "seconds": time.time() - start,
    "count": int(dh.size),
    "mean_m": float(np.mean(dh)),
    "median_m": float(np.median(dh)),
    "nmad_m": float(xdem.spatialstats.nmad(dh)),
    "le90_m": float(np.percentile(dh, 95) - np.percentile(dh, 5)),
}))
