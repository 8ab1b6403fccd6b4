#!/usr/bin/env python3
"""High-precision reference for the QSC projection on an ellipsoid (ECM), with mpmath.

A direct transcription of the published formulas (O'Neill & Laubscher 1976 as implemented in
PROJ's qsc.cpp, with the geocentric shift of Lambers & Kolb 2012), evaluated with 60 significant
digits. The acos-based forms lose up to half of the digits near a face centre, which still
leaves more than 40 correct digits. Inputs are IEEE doubles written by the Rust tests; each is
converted exactly (mpf(float(text))).

stdin lines:
  fwd A B FACE LAT_DEG LON_DEG   -> "X Y"          (face coordinates, PROJ metres / A)
  inv A B FACE X Y               -> "LAT_DEG LON_DEG"
FACE is PROJ's number 0-5. Output has 30 significant digits.
"""
import sys
from mpmath import mp, mpf, atan, atan2, acos, asin, sqrt, sin, cos, tan, pi, nstr

mp.dps = 60
FRONT, RIGHT, BACK, LEFT, TOP, BOTTOM = range(6)


def rad(deg):
    return mpf(deg) * pi / 180


def fwd(a, b, face, lat, lon):
    # geocentric shift: tan(psi) = (b/a)^2 tan(phi)
    if abs(lat) == pi / 2:
        psi = lat
    else:
        psi = atan((b / a) ** 2 * tan(lat))
    if face == TOP:
        phi = pi / 2 - psi
        lon_n = lon
        # theta measured as in PROJ's AREA logic: reduce lon into an area
        if pi / 4 <= lon_n <= 3 * pi / 4:
            area, theta = 0, lon_n - pi / 2
        elif lon_n > 3 * pi / 4 or lon_n <= -3 * pi / 4:
            area, theta = 1, (lon_n - pi if lon_n > 0 else lon_n + pi)
        elif -3 * pi / 4 < lon_n <= -pi / 4:
            area, theta = 2, lon_n + pi / 2
        else:
            area, theta = 3, lon_n
    elif face == BOTTOM:
        phi = pi / 2 + psi
        lon_n = lon
        if pi / 4 <= lon_n <= 3 * pi / 4:
            area, theta = 0, -lon_n + pi / 2
        elif -pi / 4 <= lon_n < pi / 4:
            area, theta = 1, -lon_n
        elif -3 * pi / 4 <= lon_n < -pi / 4:
            area, theta = 2, -lon_n - pi / 2
        else:
            area, theta = 3, (-lon_n + pi if lon_n > 0 else -lon_n - pi)
    else:
        q = cos(psi) * cos(lon)
        r = cos(psi) * sin(lon)
        s = sin(psi)
        if face == FRONT:
            phi, xx, yy = acos(q), r, s
        elif face == RIGHT:
            phi, xx, yy = acos(r), -q, s
        elif face == BACK:
            phi, xx, yy = acos(-q), -r, s
        else:
            phi, xx, yy = acos(-r), q, s
        if phi == 0:
            return mpf(0), mpf(0)
        theta = atan2(yy, xx)
        if abs(theta) <= pi / 4:
            area = 0
        elif pi / 4 < theta <= 3 * pi / 4:
            area, theta = 1, theta - pi / 2
        elif theta > 3 * pi / 4 or theta <= -3 * pi / 4:
            area, theta = 2, (theta - pi if theta >= 0 else theta + pi)
        else:
            area, theta = 3, theta + pi / 2
    if phi == 0:
        return mpf(0), mpf(0)
    mu = atan((12 / pi) * (theta + acos(sin(theta) * cos(pi / 4)) - pi / 2))
    t = sqrt((1 - cos(phi)) / (cos(mu) ** 2) / (1 - cos(atan(1 / cos(theta)))))
    mu += area * pi / 2
    return t * cos(mu), t * sin(mu)


def inv(a, b, face, x, y):
    nu = atan(sqrt(x * x + y * y))
    mu = atan2(y, x)
    if x >= 0 and x >= abs(y):
        area = 0
    elif y >= 0 and y >= abs(x):
        area, mu = 1, mu - pi / 2
    elif x < 0 and -x >= abs(y):
        area, mu = 2, (mu + pi if mu < 0 else mu - pi)
    else:
        area, mu = 3, mu + pi / 2
    t = (pi / 12) * tan(mu)
    theta = atan(sin(t) / (cos(t) - 1 / sqrt(2)))
    cosphi = 1 - cos(mu) ** 2 * tan(nu) ** 2 * (1 - cos(atan(1 / cos(theta))))
    phi = acos(cosphi)
    if face in (TOP, BOTTOM):
        if face == TOP:
            lat = pi / 2 - phi
            lon = [theta + pi / 2, (theta + pi if theta < 0 else theta - pi), theta - pi / 2, theta][area]
        else:
            lat = phi - pi / 2
            lon = [-theta + pi / 2, -theta, -theta - pi / 2, (-theta - pi if theta < 0 else -theta + pi)][area]
    else:
        q = cosphi
        s = sin(phi) * sin(theta)
        r = sqrt(max(mpf(0), 1 - q * q - s * s))
        if area == 1:
            r, s = -s, r
        elif area == 2:
            r, s = -r, -s
        elif area == 3:
            r, s = s, -r
        if face == RIGHT:
            q, r = -r, q
        elif face == BACK:
            q, r = -q, -r
        elif face == LEFT:
            q, r = r, -q
        lat = asin(s)
        lon = atan2(r, q)
    # sphere -> ellipsoid: tan(phi) = (a/b)^2 tan(psi)
    if abs(lat) != pi / 2:
        lat = atan((a / b) ** 2 * tan(lat))
    if lon <= -pi:
        lon += 2 * pi
    if lon > pi:
        lon -= 2 * pi
    return lat * 180 / pi, lon * 180 / pi


def main():
    out = []
    for line in sys.stdin:
        f = line.split()
        if not f:
            continue
        a, b, face = mpf(float(f[1])), mpf(float(f[2])), int(f[3])
        u, v = mpf(float(f[4])), mpf(float(f[5]))
        if f[0] == "fwd":
            x, y = fwd(a, b, face, rad(u), rad(v))
        else:
            x, y = inv(a, b, face, u, v)
        out.append(nstr(x, 30, min_fixed=-1, max_fixed=1) + " " + nstr(y, 30, min_fixed=-1, max_fixed=1))
    sys.stdout.write("\n".join(out) + "\n")


main()
