#!/usr/bin/env python3
"""Reference sun positions from pvlib's NREL SPA (an independent implementation) for
tests/sun_reference.rs and the `previz sun --batch` integration test.

Writes tests/data/sun/pvlib_spa_reference.csv. Columns utc..delta_t_s are the inputs, in the
layout `previz sun --batch` reads; pvlib_* are pvlib's outputs (degrees); `kind` says why the
case is there:
  published  the NREL SPA test case (Reda & Andreas, Table A5.1)
  random     uniform instants in 1600-3000, places uniform over the sphere, elevation 0-4000 m,
             pressure = standard atmosphere +-5 %, temperature -30..40 C, ΔT from
             pvlib.spa.calculate_deltat (Espenak & Meeus)
  pole       latitude +-90 at several longitudes and seasons
  dateline   longitude +-180 and +-179.9999
  sunrise / sunset   the instants pvlib's transit_sunrise_sunset returns for random days and
             places (the sun's centre about 0.833 deg below the horizon)

pvlib is called at its lowest level (pvlib.spa.solar_position_numpy with Unix seconds), since
pandas timestamps cannot hold years before 1677 or after 2262. atmos_refract = 0.5667 as in SPA.

Run from the repository root:  pip install pvlib==0.16.1 && python3 tests/data/sun/make_pvlib_reference.py
"""
import csv
import datetime as dt
import math
import pathlib
import random
import warnings

import numpy as np
import pvlib
from pvlib import spa

OUT = pathlib.Path("tests/data/sun/pvlib_spa_reference.csv")
EPOCH = dt.datetime(1970, 1, 1, tzinfo=dt.timezone.utc)
REFRACTION_CUT = -(0.26667 + 0.5667)

rng = random.Random(20261121)


def unix(t):
    return (t - EPOCH) // dt.timedelta(microseconds=1) / 1e6


def iso(t):
    return t.strftime("%Y-%m-%dT%H:%M:%S.%fZ")


def std_pressure(h):
    return 1013.25 * (1 - 0.0065 * h / 288.15) ** 5.255877


def deltat(t):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return float(spa.calculate_deltat(t.year, t.month))


def pvlib_position(t, lat, lon, elev, p, temp, d):
    r = spa.solar_position_numpy(np.array([unix(t)]), lat, lon, elev, p, temp, d, 0.5667, 1)
    theta, theta0, _e, e0, phi, _eot = (float(x[0]) for x in r)
    return theta0, theta, phi, e0


def random_instant(first_year, last_year):
    a = dt.datetime(first_year, 1, 1, tzinfo=dt.timezone.utc)
    b = dt.datetime(last_year + 1, 1, 1, tzinfo=dt.timezone.utc)
    return a + dt.timedelta(microseconds=rng.randrange((b - a) // dt.timedelta(microseconds=1)))


rows = []


def add(kind, t, lat, lon, elev, p, temp, d):
    zen, app, az, e0 = pvlib_position(t, lat, lon, elev, p, temp, d)
    if abs(e0 - REFRACTION_CUT) < 1e-6:
        # Too close to SPA's refraction switch to compare two implementations; move 1 s.
        t += dt.timedelta(seconds=1)
        zen, app, az, e0 = pvlib_position(t, lat, lon, elev, p, temp, d)
    rows.append([iso(t), repr(lat), repr(lon), repr(elev), repr(p), repr(temp), repr(d),
                 kind, repr(zen), repr(app), repr(az)])


# The published case: 2003-10-17 12:30:30 at UTC-7.
add("published", dt.datetime(2003, 10, 17, 19, 30, 30, tzinfo=dt.timezone.utc),
    39.742476, -105.1786, 1830.14, 820.0, 11.0, 67.0)

for _ in range(400):
    t = random_instant(1600, 3000)
    lat = math.degrees(math.asin(rng.uniform(-1, 1)))
    lon = rng.uniform(-180, 180)
    elev = rng.uniform(0, 4000)
    add("random", t, lat, lon, elev, std_pressure(elev) * rng.uniform(0.95, 1.05),
        rng.uniform(-30, 40), deltat(t))

for lat in (90.0, -90.0):
    for month in (1, 3, 6, 9, 12):
        for lon in (0.0, 123.4):
            t = dt.datetime(2020 + month, month, 21, rng.randrange(24), 17, 5, tzinfo=dt.timezone.utc)
            add("pole", t, lat, lon, 0.0, 1013.25, 10.0, deltat(t))

for lon in (180.0, -180.0, 179.9999, -179.9999):
    for lat in (-45.0, 0.0, 45.0):
        t = random_instant(1900, 2100)
        add("dateline", t, lat, lon, 0.0, 1013.25, 10.0, deltat(t))

for _ in range(25):
    day = random_instant(1700, 2200).replace(hour=0, minute=0, second=0, microsecond=0)
    lat = rng.uniform(-60, 60)
    lon = rng.uniform(-180, 180)
    d = deltat(day)
    _transit, rise, sett = spa.transit_sunrise_sunset(np.array([unix(day)]), lat, lon, d, 1)
    for kind, s in (("sunrise", rise[0]), ("sunset", sett[0])):
        t = EPOCH + dt.timedelta(microseconds=round(float(s) * 1e6))
        add(kind, t, lat, lon, 0.0, 1013.25, 10.0, d)

with OUT.open("w", newline="") as f:
    w = csv.writer(f, lineterminator="\n")
    w.writerow(["utc", "lat", "lon", "elevation_m", "pressure_mbar", "temperature_c", "delta_t_s",
                "kind", "pvlib_zenith_deg", "pvlib_apparent_zenith_deg", "pvlib_azimuth_deg"])
    w.writerows(rows)
print(f"wrote {len(rows)} cases to {OUT} (pvlib {pvlib.__version__})")
