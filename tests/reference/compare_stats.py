"""Reference statistics of a `terrafuse compare --samples` CSV, for tests/compare.rs.

Unweighted: numpy and xDEM (xdem.spatialstats.nmad), as xDEM reports them for a dh array.
Weighted by the cell areas: numpy.average for the moments; quantiles by the definition in
src/compare/stats.rs (numpy's linear interpolation generalised to weights), written here anew.
Prints one JSON object: {"samples": {...}, "area": {...}}.
"""
import json
import sys

import numpy as np
import xdem


def weighted_quantile(x, w, p):
    order = np.argsort(x, kind="stable")
    x, w = x[order], w[order]
    if len(x) == 1:
        return float(x[0])
    cum = np.cumsum(w) - w[0]  # W_k - w_0
    return float(np.interp(p * cum[-1], cum, x))


def main(path):
    data = np.genfromtxt(path, delimiter=",", names=True)
    dh = data["dh_m"].astype(float)
    area = data["area_m2"].astype(float)
    plain = {
        "count": int(dh.size),
        "mean_m": float(np.mean(dh)),
        "median_m": float(np.median(dh)),
        "std_m": float(np.std(dh)),
        "rmse_m": float(np.sqrt(np.mean(dh**2))),
        "nmad_m": float(xdem.spatialstats.nmad(dh)),
        "min_m": float(np.min(dh)),
        "max_m": float(np.max(dh)),
        "le90_m": float(np.percentile(dh, 95) - np.percentile(dh, 5)),
        "p90_abs_m": float(np.percentile(np.abs(dh), 90)),
    }
    mean = np.average(dh, weights=area)
    median = weighted_quantile(dh, area, 0.5)
    weighted = {
        "count": int(dh.size),
        "mean_m": float(mean),
        "median_m": median,
        "std_m": float(np.sqrt(np.average((dh - mean) ** 2, weights=area))),
        "rmse_m": float(np.sqrt(np.average(dh**2, weights=area))),
        "nmad_m": 1.4826 * weighted_quantile(np.abs(dh - median), area, 0.5),
        "min_m": float(np.min(dh)),
        "max_m": float(np.max(dh)),
        "le90_m": weighted_quantile(dh, area, 0.95) - weighted_quantile(dh, area, 0.05),
        "p90_abs_m": weighted_quantile(np.abs(dh), area, 0.9),
        "area_km2": float(np.sum(area) / 1e6),
    }
    print(json.dumps({"samples": plain, "area": weighted}))


if __name__ == "__main__":
    main(sys.argv[1])
