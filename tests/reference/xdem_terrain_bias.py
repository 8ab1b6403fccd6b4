"""xDEM's TerrainBias("elevation") on two rasters of the same projected grid, for
tests/compare.rs.

usage: xdem_terrain_bias.py REFERENCE.tif TO_ALIGN.tif H1,H2,…

Fits TerrainBias(terrain_attribute="elevation", bin_sizes=100, bin_statistic=nanmedian,
bin_apply_method="linear") and prints JSON: "bias_at", the correction it takes off the second
raster at the pixels whose reference elevation is within 2 m of each H (their median, metres);
"nmad_after", the NMAD of the difference after it; "seconds".
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
heights = [float(h) for h in sys.argv[3].split(",")]
start = time.time()
coreg = xdem.coreg.TerrainBias(
    terrain_attribute="elevation", bin_sizes=100, bin_statistic=np.nanmedian, bin_apply_method="linear"
)
coreg.fit(reference, to_align)
corrected = coreg.apply(to_align)
seconds = time.time() - start
ref = np.ma.filled(reference.data, np.nan).astype(np.float64)
tba = np.ma.filled(to_align.data, np.nan).astype(np.float64)
cor = np.ma.filled(corrected.data, np.nan).astype(np.float64)
correction = tba - cor
bias_at = []
for h in heights:
    near = np.isfinite(correction) & (np.abs(ref - h) < 2.0)
    bias_at.append(float(np.median(correction[near])) if near.any() else None)
print(
    json.dumps(
        {"bias_at": bias_at, "nmad_after": float(xdem.spatialstats.nmad(cor - ref)), "seconds": seconds}
    )
)
