"""xDEM's DirectionalBias on two rasters of the same projected grid, for tests/compare.rs.

usage: xdem_directional.py REFERENCE.tif TO_ALIGN.tif AZIMUTH

Fits DirectionalBias(angle=90 − AZIMUTH) (xDEM's angle is counter-clockwise from the x axis, the
azimuth clockwise from north) with its defaults and prints JSON: "fit_params" (xDEM's sum of
sinusoids as it reports them), "nmad_after" (of the difference after it), "seconds".
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
start = time.time()
coreg = xdem.coreg.DirectionalBias(angle=90.0 - float(sys.argv[3]))
coreg.fit(reference, to_align)
corrected = coreg.apply(to_align)
seconds = time.time() - start
params = [float(v) for v in np.ravel(coreg.meta["outputs"]["fitorbin"]["fit_params"])]
nmad = float(xdem.spatialstats.nmad((corrected - reference).data.compressed()))
print(json.dumps({"fit_params": params, "nmad_after": nmad, "seconds": seconds}))
