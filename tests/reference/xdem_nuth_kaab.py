"""xDEM's Nuth & Kääb co-registration of two rasters on the same projected grid, for
tests/compare.rs. Prints {"shift_x", "shift_y", "shift_z", "seconds"}: the translation xDEM applies
to the second raster (metres in its CRS) to align it with the first.
"""
import json
import sys
import time
import warnings

warnings.filterwarnings("ignore")
import xdem  # noqa: E402

reference = xdem.DEM(sys.argv[1])
to_align = xdem.DEM(sys.argv[2])
start = time.time()
coreg = xdem.coreg.NuthKaab()
coreg.fit(reference, to_align)
matrix = coreg.to_matrix()
print(json.dumps({
    "shift_x": float(matrix[0, 3]),
    "shift_y": float(matrix[1, 3]),
    "shift_z": float(matrix[2, 3]),
    "seconds": time.time() - start,
}))
