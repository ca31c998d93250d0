#!/usr/bin/env python3
"""Writes the small SOFA (AES69) files the tests read (needs `pip install netCDF4 numpy`).

    python3 rooms/tools/gen_sofa.py

Writes into tests/data/ (committed, so the tests need neither Python nor a download):
  directivity_cardioid.sofa  FreeFieldDirectivityTF: a source whose pressure gain is the
                             first-order pattern a(f) + (1 - a(f)) cos(theta) about +x, with
                             a(f) = 1 (omni) below 177 Hz, 1/2 (cardioid) up to 1414 Hz, 1/4
                             (hypercardioid) above: the 63/125 Hz bands are omni, 250 Hz-1 kHz
                             cardioid, 2-8 kHz hypercardioid. Directions: a 10-degree grid of
                             azimuth and elevation (receivers on a 2 m sphere), frequencies in
                             third octaves 50 Hz-10 kHz, an arbitrary level and phase (a
                             balloon's normalisation must not depend on them).
  directivity_fir.sofa       GeneralFIR: a cardioid in every band as impulse responses at
                             48 kHz (a scaled, delayed unit impulse per direction), receivers
                             on the same grid in cartesian coordinates.
  hrir_delays.sofa           SimpleFreeFieldHRIR: each ear's impulse response a unit impulse
                             delayed by the spherical-head (Woodworth) path to that ear, a = 8.75
                             cm, c = 343 m/s, on a 10-degree grid; 48 kHz, 256 taps.

The files are netCDF-4 (HDF5), as the SOFA API for Matlab and the netCDF library write them.
"""
import math
import os

import netCDF4
import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
OUT = os.path.join(os.path.dirname(os.path.dirname(HERE)), "tests", "data")


def grid(step_deg=10):
    """Azimuth/elevation pairs in degrees: a ring every step, the poles once."""
    dirs = []
    for el in range(-90, 91, step_deg):
        if abs(el) == 90:
            dirs.append((0.0, float(el)))
            continue
        for az in range(0, 360, step_deg):
            dirs.append((float(az), float(el)))
    return dirs


def cart(az, el):
    a, e = math.radians(az), math.radians(el)
    return (math.cos(e) * math.cos(a), math.cos(e) * math.sin(a), math.sin(e))


def common(ds, conventions, data_type, m, r, n, fixed_source=True):
    ds.Conventions = "SOFA"
    ds.Version = "2.1"
    ds.SOFAConventions = conventions
    ds.SOFAConventionsVersion = "1.0"
    ds.DataType = data_type
    ds.APIName = "propsim rooms/tools/gen_sofa.py"
    ds.APIVersion = "1.0"
    ds.RoomType = "free field"
    ds.Title = "propsim test data"
    ds.AuthorContact = "propsim"
    ds.Organization = "propsim"
    ds.License = "CC0"
    ds.DateCreated = "2026-11-26 00:00:00"
    ds.DateModified = "2026-11-26 00:00:00"
    ds.createDimension("I", 1)
    ds.createDimension("C", 3)
    ds.createDimension("M", m)
    ds.createDimension("R", r)
    ds.createDimension("E", 1)
    ds.createDimension("N", n)
    for name in ("ListenerPosition", "SourcePosition") if fixed_source else ("ListenerPosition",):
        v = ds.createVariable(name, "f8", ("I", "C"))
        v.Type = "cartesian"
        v.Units = "metre"
        v[:] = np.zeros((1, 3))
    v = ds.createVariable("EmitterPosition", "f8", ("E", "C", "I"))
    v.Type = "cartesian"
    v.Units = "metre"
    v[:] = np.zeros((1, 3, 1))
    v = ds.createVariable("ListenerView", "f8", ("I", "C"))
    v.Type = "cartesian"
    v.Units = "metre"
    v[:] = np.array([[1.0, 0.0, 0.0]])
    v = ds.createVariable("ListenerUp", "f8", ("I", "C"))
    v[:] = np.array([[0.0, 0.0, 1.0]])


def a_of(f_hz):
    if f_hz < 177.0:
        return 1.0
    if f_hz < 1414.0:
        return 0.5
    return 0.25


def directivity_tf():
    dirs = grid()
    freqs = [1000.0 * 2.0 ** (k / 3.0) for k in range(-13, 11)]  # 50 Hz-10 kHz
    path = os.path.join(OUT, "directivity_cardioid.sofa")
    with netCDF4.Dataset(path, "w", format="NETCDF4") as ds:
        common(ds, "FreeFieldDirectivityTF", "TF", 1, len(dirs), len(freqs))
        v = ds.createVariable("ReceiverPosition", "f8", ("R", "C", "I"))
        v.Type = "spherical"
        v.Units = "degree, degree, metre"
        v[:] = np.array([[[az], [el], [2.0]] for az, el in dirs])
        n = ds.createVariable("N", "f8", ("N",))
        n.LongName = "frequency"
        n.Units = "hertz"
        n[:] = np.array(freqs)
        re = np.zeros((1, len(dirs), len(freqs)))
        im = np.zeros((1, len(dirs), len(freqs)))
        for r, (az, el) in enumerate(dirs):
            c = cart(az, el)[0]
            for k, f in enumerate(freqs):
                a = a_of(f)
                g = 0.37 * (a + (1.0 - a) * c)  # an arbitrary level
                phase = 2.0 * math.pi * f * 2.0 / 343.0
                re[0, r, k] = g * math.cos(phase)
                im[0, r, k] = -g * math.sin(phase)
        ds.createVariable("Data.Real", "f8", ("M", "R", "N"), zlib=True)[:] = re
        ds.createVariable("Data.Imag", "f8", ("M", "R", "N"), zlib=True)[:] = im
    print("wrote", path)


def directivity_fir():
    dirs = grid()
    taps = 64
    path = os.path.join(OUT, "directivity_fir.sofa")
    with netCDF4.Dataset(path, "w", format="NETCDF4") as ds:
        common(ds, "GeneralFIR", "FIR", 1, len(dirs), taps)
        v = ds.createVariable("ReceiverPosition", "f8", ("R", "C", "I"))
        v.Type = "cartesian"
        v.Units = "metre"
        v[:] = np.array([[[2.0 * x] for x in cart(az, el)] for az, el in dirs])
        ds.createVariable("Data.SamplingRate", "f8", ("I",))[:] = np.array([48000.0])
        ds.createVariable("Data.Delay", "f8", ("I", "R"))[:] = np.zeros((1, len(dirs)))
        ir = np.zeros((1, len(dirs), taps))
        for r, (az, el) in enumerate(dirs):
            ir[0, r, 3] = 0.5 * (0.5 + 0.5 * cart(az, el)[0])
        ds.createVariable("Data.IR", "f8", ("M", "R", "N"), zlib=True)[:] = ir
    print("wrote", path)


def hrir_delays():
    dirs = grid()
    taps = 256
    fs = 48000.0
    radius_m, c = 0.0875, 343.0
    path = os.path.join(OUT, "hrir_delays.sofa")
    with netCDF4.Dataset(path, "w", format="NETCDF4") as ds:
        common(ds, "SimpleFreeFieldHRIR", "FIR", len(dirs), 2, taps, fixed_source=False)
        ds.createVariable("ReceiverPosition", "f8", ("R", "C", "I"))[:] = np.array(
            [[[0.0], [radius_m], [0.0]], [[0.0], [-radius_m], [0.0]]]
        )
        sp = ds.createVariable("SourcePosition", "f8", ("M", "C"))
        sp.Type = "spherical"
        sp.Units = "degree, degree, metre"
        sp[:] = np.array([[az, el, 1.5] for az, el in dirs])
        ds.createVariable("Data.SamplingRate", "f8", ("I",))[:] = np.array([fs])
        ds.createVariable("Data.Delay", "f8", ("I", "R"))[:] = np.zeros((1, 2))
        ir = np.zeros((len(dirs), 2, taps))
        for m, (az, el) in enumerate(dirs):
            x, y, z = cart(az, el)
            for ear, side in ((0, 1.0), (1, -1.0)):
                # Woodworth: the angle between the direction and the ear's axis decides the
                # path; the near ear's extra path is -a cos(angle), the far ear's
                # a (angle - pi/2) around the head (both relative to the centre).
                cos_ear = max(-1.0, min(1.0, side * y))
                ang = math.acos(cos_ear)
                extra = -radius_m * cos_ear if ang <= math.pi / 2 else radius_m * (ang - math.pi / 2)
                t = 40 + extra / c * fs
                i = int(round(t))
                ir[m, ear, i] = 1.0
        ds.createVariable("Data.IR", "f8", ("M", "R", "N"), zlib=True)[:] = ir
    print("wrote", path)


if __name__ == "__main__":
    os.makedirs(OUT, exist_ok=True)
    directivity_tf()
    directivity_fir()
    hrir_delays()
