"""xDEM's Deramp(poly_order) on two rasters of the same projected grid (metres), for
tests/compare.rs. Prints {"centre", "east_10km", "north_10km", "seconds"}: the correction xDEM
takes off the second raster at the grid's centre and 10 km east and north of it (metres).
"""
import json
import sys
import time
import warnings

warnings.filterwarnings("ignore")
import numpy as np  # noqa: E402
import xdem  # noqa: E402

reference = xdem.DEM(sys.argv[1])
to_align = xdem.DEM(sys.argv[2])
order = int(sys.argv[3])
start = time.time()
coreg = xdem.coreg.Deramp(poly_order=order)
coreg.fit(reference, to_align)
corrected = coreg.apply(to_align)
seconds = time.time() - start
correction = np.ma.filled(to_align.data - corrected.data, np.nan).astype(np.float64)
t = to_align.transform


def at(x, y):
    col = (x - t.c) / t.a - 0.5
    row = (y - t.f) / t.e - 0.5
    c0, r0 = int(np.floor(col)), int(np.floor(row))
    fc, fr = col - c0, row - r0
    w = correction[r0:r0 + 2, c0:c0 + 2]
    return float((w[0, 0] * (1 - fc) + w[0, 1] * fc) * (1 - fr) + (w[1, 0] * (1 - fc) + w[1, 1] * fc) * fr)


print(json.dumps({"centre": at(0.0, 0.0), "east_10km": at(10000.0, 0.0), "north_10km": at(0.0, 10000.0),
                  "seconds": seconds}))
