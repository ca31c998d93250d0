"""propsim: one ray-tracing core for images, room acoustics and radio coverage.

Four functions run the simulators of the ``propsim`` command line on one scene (a ``.toml``
scene file, a bare OBJ, or ``builtin:NAME``) and return dicts of numpy arrays and plain
values::

    import propsim
    img = propsim.render(spp=16)["image"]                      # (h, w, 3) float32 radiance
    ac = propsim.acoustic("builtin:shoebox", rays=20000)
    ac["metrics"][0, :, ac["metric_names"].index("t30_s")]     # T30 per octave band, s
    rf = propsim.rf("scene.toml", freq_ghz=28, tx=(0, 0, 10))  # rf["path_gain"]: (tx, ny, nx)

Options are the command line's flags with underscores (``--ism-order 1`` is ``ism_order=1``,
``--no-air`` is ``no_air=True``, ``--tx 1,2,3`` is ``tx=(1, 2, 3)``); their defaults are the
command line's. ``out=DIR`` also writes the files the command line writes. Bad options, bad
values and scenes that cannot run raise :class:`PropsimError` with the command line's one-line
message. The simulations release the GIL and use every core unless ``threads=N``.
docs/python.md describes every returned value with its shape and unit.
"""

import os as _os
import warnings as _warnings

from . import _propsim
from ._propsim import PropsimError, __version__

__all__ = ["render", "acoustic", "rf", "run", "PropsimError", "PropsimWarning", "__version__"]


class PropsimWarning(UserWarning):
    """What the command line prints as ``warning:`` (a scene or a result to take with care)."""


def _scene(scene):
    """A scene path as a string (``str``, ``pathlib.Path`` or ``builtin:NAME``)."""
    try:
        return _os.fspath(scene)
    except TypeError:
        raise PropsimError(f"scene: expected a path or builtin:NAME, got {type(scene).__name__}") from None


def _warn(result):
    """Issues the result's warnings as :class:`PropsimWarning` and returns the result."""
    for w in result.get("warnings", ()):
        _warnings.warn(w, PropsimWarning, stacklevel=3)
    return result


def render(scene="builtin:cornell_box_classic", **options):
    """Renders an image of ``scene``: ``propsim render`` in memory.

    Options (defaults: the scene's, else the command line's): ``width``, ``height``, ``spp``,
    ``max_depth``, ``integrator`` (a name of ``propsim render --integrator``: "path",
    "bdpt", "spectral", ...), ``spectral`` (True: the same as ``integrator="spectral"``),
    ``seed`` (0),
    ``eye``, ``target``, ``up`` (points), ``fov_deg``, ``exposure``, ``tone_map``,
    ``clamp_indirect``, ``materials`` (list of files), ``up_axis``, ``scale``, ``threads``;
    ``out=DIR`` writes ``DIR/render.png``, ``output=FILE`` writes a .png, .exr or .npy file.

    Returns a dict: ``image`` (float32, height x width x 3, linear radiance, not tone
    mapped), ``settings``, ``camera``, ``seconds``, ``samples``, ``rays``, ``warnings``,
    ``files``.
    """
    return _warn(_propsim.render(_scene(scene), options))


def acoustic(scene="builtin:bras_cr2", sources=None, receivers=None, **options):
    """Simulates the room acoustics of ``scene``: ``propsim acoustic`` in memory.

    ``sources`` and ``receivers`` are lists of points (x, y, z) in metres replacing the
    scene's (named S1, S2, ... and R1, R2, ...); without them the scene's are used, else one
    of each is placed in the room. Options: ``rays`` (per source; the scene's, else 200000),
    ``seed`` (1), ``ism_order`` (2), ``max_time_s``, ``receiver_radius_m``, ``no_air``,
    ``no_diffuse_rain``, ``no_splitting``, ``roulette_db``, ``temperature_c``,
    ``humidity_percent``, ``materials``, ``up_axis``, ``scale``, ``threads``, ``out``.

    Returns a dict: ``histogram`` (float64, pairs x bands x bins, energy fluence in J/m^2 per
    joule emitted per ``bin_s`` bin: the direct sound at d metres gives 1/(4 pi d^2)),
    ``metrics`` (float64, pairs x bands x 15, columns ``metric_names``, NaN where undefined),
    ``impulse_responses`` (one float32 array per pair at ``sample_rate_hz`` = 48000, the
    WAV files' samples), ``pairs`` (source, receiver, distance, ... per pair), ``bands_hz``,
    ``sabine_s``, ``eyring_s``, ``volume_m3``, ``surface_m2``, ``speed_of_sound_m_s``,
    ``sources``, ``receivers``, ``settings``, ``notes``, ``warnings``, ``files``.
    """
    if sources is not None:
        options["sources"] = sources
    if receivers is not None:
        options["receivers"] = receivers
    return _warn(_propsim.acoustic(_scene(scene), options))


def rf(scene, **options):
    """Computes the radio coverage of ``scene``: ``propsim rf`` in memory.

    Options (defaults: the scene's, else the command line's): ``tx`` (one transmitter at a
    point), ``freq_ghz`` (3.5), ``tx_power_dbm`` (30), ``antenna``, ``polarization``,
    ``orientation``, ``grid_height`` (1.5), ``cell_m`` (1), ``grid_min``, ``grid_max``,
    ``rays`` (10^6), ``max_depth`` (3), ``seed``, ``rx`` (list of points),
    ``no_receivers``, ``no_transmission``, ``no_diffraction``, ``extrapolate``,
    ``wall_thickness_m``, ``scattering_coefficient``, ``cfr_bandwidth_mhz``, ``cfr_points``,
    ``materials``, ``up_axis``, ``scale``, ``threads``, ``out``.

    Returns a dict: ``path_gain`` (float64, transmitters x ny x nx, linear; Sionna RT's
    ``RadioMap.path_gain`` layout), ``x_m`` and ``y_m`` (cell centres), ``grid``,
    ``transmitters``, ``receivers``, ``summary`` (coverage.json's content), ``seconds``,
    ``warnings``, ``files``; with point receivers ``paths`` (float64, one row per path,
    columns ``paths_columns``) and, with ``cfr_bandwidth_mhz``, ``cfr`` (complex128,
    transmitters x receivers x points) at ``cfr_offsets_hz`` from each carrier.
    """
    return _warn(_propsim.rf(_scene(scene), options))


def run(scene="builtin:showcase", out="out", **options):
    """Runs the picture, the sound and the radio coverage of ``scene`` into ``out``:
    ``propsim run``. A part that cannot run is skipped with the reason in the manifest.

    Options: ``seed`` (1), ``only`` (list of "render", "acoustic", "rf"), ``quick``, ``tx``,
    ``extrapolate``, ``width``, ``height``, ``spp``, ``rays``, ``rf_rays``, ``materials``,
    ``up_axis``, ``scale``, ``threads``.

    Returns the manifest (manifest.json) as a dict: parts run or skipped and why, the
    parameters, timings and every file written, plus ``notes`` and ``warnings`` (the lines the
    command line prints as ``note:`` and ``warning:``; the warnings are also issued as
    :class:`PropsimWarning`).
    """
    options["out"] = _os.fspath(out)
    return _warn(_propsim.run(_scene(scene), options))
