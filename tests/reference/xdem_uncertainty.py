"""xDEM's spatial statistics (Hugonnet et al. 2022, xdem.spatialstats) on the samples Terrafuse
used, for tests/compare.rs.

usage: xdem_uncertainty.py SAMPLES.csv MODEL.json LAGS AREAS

SAMPLES.csv: east_m, north_m, dh_m, slope_deg, max_curvature, area_m2, stable, in_area, sigma_m
(one row per sample; sigma_m is Terrafuse's modelled error there). MODEL.json: Terrafuse's
`uncertainty` object (its bin edges are reused, so both bin the same samples alike).

Prints JSON:
- nmad_m: xDEM's nd_binning NMAD of dh on stable samples in Terrafuse's 2-D bins;
- mean_error_m: the mean over the area of xDEM's own error model (nd_binning, interp_nd_binning,
  two-step standardisation with Terrafuse's bins);
- models: the sum of two spherical models xDEM fits (fit_sum_model_variogram) to its empirical
  variogram (sample_empirical_variogram, pdist_point, Dowd) of dh / sigma_m on stable samples;
- gamma_at: that model at LAGS (metres, comma-separated); empirical: [lag, γ, pairs] per bin;
- sigma_mean_m: mean(sigma_m over the area) / sqrt(N_eff), N_eff from xDEM's
  neff_circular_approx_numerical on the area (as spatial_error_propagation with a numeric area);
  sigma_disks_m: the same for disks of AREAS (m², comma-separated);
- seconds.
"""
import json
import sys
import time
import warnings

warnings.filterwarnings("ignore")
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402
import xdem  # noqa: E402
from xdem import spatialstats as ss  # noqa: E402

samples = pd.read_csv(sys.argv[1])
model = json.load(open(sys.argv[2]))
start = time.time()
h = model["heteroscedasticity"]
slope_edges = np.array(h["slope_edges_deg"])
curv_edges = np.array(h["max_curvature_edges"])
# Terrafuse's last edge is the largest value, counted in the last bin: nudge it up so scipy's
# half-open bins count it too.
slope_edges[-1] = np.nextafter(slope_edges[-1], np.inf)
curv_edges[-1] = np.nextafter(curv_edges[-1], np.inf)

stable = samples[(samples.stable == 1) & np.isfinite(samples.dh_m) & np.isfinite(samples.max_curvature)]
dh = stable.dh_m.values
binned = ss.nd_binning(
    values=dh,
    list_var=[stable.slope_deg.values, stable.max_curvature.values],
    list_var_names=["slope", "maxc"],
    statistics=[xdem.spatialstats.nmad],
    list_var_bins=(slope_edges, curv_edges),
)
two_d = binned[binned.nd == 2]
nmad = np.full((len(slope_edges) - 1, len(curv_edges) - 1), np.nan)
for _, row in two_d.iterrows():
    i = int(np.searchsorted(slope_edges, row.slope.left, side="right") - 1)
    j = int(np.searchsorted(curv_edges, row.maxc.left, side="right") - 1)
    if row["count"] >= 100:
        nmad[i, j] = row["nmad"]

_, error_fun = ss._estimate_model_heteroscedasticity(
    dvalues=dh,
    list_var=[stable.slope_deg.values, stable.max_curvature.values],
    list_var_names=["slope", "maxc"],
    list_var_bins=(slope_edges, curv_edges),
)
area = samples[(samples.in_area == 1) & np.isfinite(samples.dh_m)]
curv_area = np.nan_to_num(area.max_curvature.values, nan=0.0)
xdem_errors = error_fun((area.slope_deg.values, curv_area))
mean_error = float(np.nanmean(xdem_errors))

z = (stable.dh_m / stable.sigma_m).values
keep = np.abs(z) <= 7 * xdem.spatialstats.nmad(z)
coords = np.c_[stable.east_m.values[keep], stable.north_m.values[keep]]
# xDEM's default bins (from √2 spacings, growing by √2, to the extent's diagonal), given
# explicitly: with coordinates instead of a grid it cannot infer the spacing.
maxlag = float(np.hypot(np.ptp(coords[:, 0]), np.ptp(coords[:, 1])))
edges = []
edge = np.sqrt(2) * float(model["spacing_m"])
while edge < maxlag:
    edges.append(edge)
    edge *= np.sqrt(2)
edges.append(maxlag)
variogram = ss.sample_empirical_variogram(
    values=z[keep],
    coords=coords,
    bin_func=edges,
    maxlag=maxlag,
    subsample=4000,
    subsample_method="pdist_point",
    estimator="dowd",
    random_state=42,
)
_, params = ss.fit_sum_model_variogram(["Sph", "Sph"], empirical_variogram=variogram)
vgm = ss.get_variogram_model_func(params)
lags = [float(x) for x in sys.argv[3].split(",")]
disks = [float(x) for x in sys.argv[4].split(",")]
mean_sigma = float(np.mean(area.sigma_m.values))
neff = ss.neff_circular_approx_numerical(area=float(area.area_m2.sum()), params_variogram_model=params)
sigma_mean = mean_sigma / np.sqrt(neff)
sigma_disks = [mean_sigma / np.sqrt(ss.neff_circular_approx_numerical(area=a, params_variogram_model=params)) for a in disks]
print(
    json.dumps(
        {
            "nmad_m": [[None if np.isnan(v) else float(v) for v in row] for row in nmad],
            "mean_error_m": mean_error,
            "models": [{"range_m": float(r), "psill": float(p)} for r, p in zip(params["range"], params["psill"])],
            "gamma_at": [float(vgm(np.array([lag]))[0]) for lag in lags],
            "empirical": [[float(r.lags), float(r.exp), int(r["count"])] for _, r in variogram.iterrows()],
            "sigma_disks_m": sigma_disks,
            "neff": float(neff),
            "sigma_mean_m": sigma_mean,
            "seconds": time.time() - start,
        }
    )
)
