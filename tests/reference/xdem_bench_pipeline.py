"""One xDEM workflow timed for `terrafuse bench compare`, in a process of its own so that its
peak memory is its own: on two rasters of one projected grid (the second reprojected onto the
first's when they differ).

usage: xdem_bench_pipeline.py REFERENCE.tif MOVED.tif WORKFLOW

WORKFLOW: nuth_kaab (NuthKaab()), nuth_kaab+deramp (NuthKaab() + Deramp(1)), nuth_kaab+terrain_bias (NuthKaab() +
TerrainBias("elevation")), or uncertainty (heteroscedasticity by slope and maximal curvature,
the variogram of the standardised dh with two spherical models, the σ of the mean over the
whole raster, as xdem.spatialstats does on stable terrain everywhere). Prints JSON: "seconds"
(reading the rasters included) and "nmad_after_m" or "sigma_mean_m" (the bench reads the
process's peak memory from /proc while it runs).
"""
import json
import sys
import time
import warnings

warnings.filterwarnings("ignore")
import numpy as np  # noqa: E402
import xdem  # noqa: E402
from xdem import spatialstats as ss  # noqa: E402

start = time.time()
reference = xdem.DEM(sys.argv[1])
moved = xdem.DEM(sys.argv[2])
if moved.shape != reference.shape or moved.transform != reference.transform:
    moved = moved.reproject(reference)
workflow = sys.argv[3]
out = {}
if workflow == "nuth_kaab":
    pipeline = xdem.coreg.NuthKaab()
    pipeline.fit(reference, moved)
    corrected = pipeline.apply(moved)
    out["nmad_after_m"] = float(ss.nmad((corrected - reference).data.compressed()))
elif workflow in ("nuth_kaab+deramp", "nuth_kaab+terrain_bias"):
    second = xdem.coreg.Deramp(poly_order=1) if workflow.endswith("deramp") else xdem.coreg.TerrainBias(
        terrain_attribute="elevation"
    )
    pipeline = xdem.coreg.NuthKaab() + second
    pipeline.fit(reference, moved)
    corrected = pipeline.apply(moved)
    out["nmad_after_m"] = float(ss.nmad((corrected - reference).data.compressed()))
elif workflow == "uncertainty":
    dh = moved - reference
    slope = xdem.terrain.slope(reference)
    maxc = xdem.terrain.max_curvature(reference)
    errors, _, _ = ss.infer_heteroscedasticity_from_stable(dvalues=dh, list_var=[slope, maxc])
    _, params, _ = ss.infer_spatial_correlation_from_stable(
        dvalues=dh, list_models=["Sph", "Sph"], errors=errors, random_state=42
    )
    area = float(np.count_nonzero(np.isfinite(np.ma.filled(dh.data, np.nan)))) * abs(reference.res[0] * reference.res[1])
    out["sigma_mean_m"] = float(ss.spatial_error_propagation(areas=[area], errors=errors, params_variogram_model=params)[0])
else:
    sys.exit(f"unknown workflow {workflow}")
out["seconds"] = time.time() - start
print(json.dumps(out))
