"""A copy of a DEM with known biases added, for tests/compare.rs: a plane in local east and north
kilometres about (LON0, LAT0) and an elevation-dependent bias,

    out = h + c0 + ge·e_km + gn·n_km + k·(h − h0) [+ A·sin(2π·x / L)],

where e_km, n_km are the longitude and latitude differences times the WGS84 radii of curvature
at LAT0 (the ellipsoid's local metres at the centre), and x = e·sin(AZ) + n·cos(AZ) metres along
an azimuth AZ (degrees clockwise from north). No data stays no data.

usage: biased_copy.py SRC OUT LON0 LAT0 C0 GE GN K H0 [A L AZ]
"""
import sys

import numpy as np
import rasterio

src, out = sys.argv[1], sys.argv[2]
lon0, lat0, c0, ge, gn, k, h0 = (float(v) for v in sys.argv[3:10])
a, f = 6378137.0, 1 / 298.257223563
e2 = f * (2 - f)
s = np.sin(np.radians(lat0))
n_radius = a / np.sqrt(1 - e2 * s * s)
m_radius = a * (1 - e2) / (1 - e2 * s * s) ** 1.5
km_per_deg_lon = np.radians(1.0) * n_radius * np.cos(np.radians(lat0)) / 1000
km_per_deg_lat = np.radians(1.0) * m_radius / 1000

with rasterio.open(src) as ds:
    h = ds.read(1).astype(np.float64)
    profile = ds.profile
    nodata = ds.nodata
    t = ds.transform
rows, cols = np.indices(h.shape)
lon = t.c + (cols + 0.5) * t.a
lat = t.f + (rows + 0.5) * t.e
e_km, n_km = (lon - lon0) * km_per_deg_lon, (lat - lat0) * km_per_deg_lat
bias = c0 + ge * e_km + gn * n_km + k * (h - h0)
if len(sys.argv) > 10:
    amplitude, wavelength, azimuth = (float(v) for v in sys.argv[10:13])
    x = 1000 * (e_km * np.sin(np.radians(azimuth)) + n_km * np.cos(np.radians(azimuth)))
    bias = bias + amplitude * np.sin(2 * np.pi * x / wavelength)
outv = np.where(h == nodata, h, h + bias)
profile.update(dtype="float32")
with rasterio.open(out, "w", **profile) as ds:
    ds.write(outv.astype(np.float32), 1)
