"""Accelerometer files -> fitted modes, Klipper's recommendation and the files' record.

The glue between the file readers (:mod:`ringtune.hardware.accel`) and the fits on arrays
(:mod:`ringtune.envs.identify`): each file is read once; a resonance spectrum is fitted per axis
and kept for Klipper's rule (the very function ``ringtune recommend --accel`` uses, so the two
agree by construction); an RRF ``M956`` capture (the ringing after one move, not a sweep) is fitted
with damped sinusoids. What the tool had to decide about a file (its axis from its columns, a sweep
that does not cover the usual band, a poor fit) is returned as a warning naming the file.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass, field
from pathlib import Path

from ringtune.agents.klipper.baseline import recommend_axes
from ringtune.envs.identify import AxisFit, identify_decay, identify_psd
from ringtune.hardware.accel import axis_from_file_name, read_accel, to_psd
from ringtune.hardware.raw_accel import RawAccel
from ringtune.shaping.errors import RingtuneError

#: Klipper's default resonance sweep, Hz ([resonance_tester] min_freq, max_freq)
SWEEP = (5.0, 135.0)

def sha256_of(path: str | Path) -> str:
    """Hex SHA-256 of a file's bytes."""
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


@dataclass
class Measurement:
    """What a set of accelerometer files says: the fits, the spectra by axis (for Klipper's rule),
    the files as recorded in ``[measurement]`` and the warnings (each naming its file)."""

    fits: list[AxisFit]
    psds: dict[str, list] = field(default_factory=dict)
    files: list[dict] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)

    def by_axis(self) -> dict[str, AxisFit]:
        """The fit used for each axis: with several files of one axis, the highest r²."""
        best: dict[str, AxisFit] = {}
        for fit in self.fits:
            if fit.axis in ("x", "y") and (fit.axis not in best or fit.r2 > best[fit.axis].r2):
                best[fit.axis] = fit
        return best


def _named_axis(path) -> str | None:
    """X or Y from the file's name (:func:`axis_from_file_name`); a Z file is refused: the printer
    model has no Z resonances."""
    ax = axis_from_file_name(path)
    if ax == "z":
        raise RingtuneError("a Z resonance test: the printer model has X and Y modes only", str(path))
    return ax


#: why a file's columns do not tell which axis it measured
UNNAMED_AXIS = ("its name does not say, and its columns cannot (on a CoreXY, or with the accelerometer "
                "turned, the largest column is not the axis tested: a real Voron 2.4 X test is largest in psd_y)")


def _axis(path, items, given: str | None) -> tuple[str, str | None]:
    if given:
        return given, None
    ax = _named_axis(path)
    if ax:
        return ax, None
    raise RingtuneError(f"cannot tell which axis this file measured: {UNNAMED_AXIS}; rename it as Klipper "
                        "names it (resonances_x_…, resonances_y_…) or give --axis", str(path))


def _free_decay_fit(path, data: RawAccel, axis: str | None, max_modes: int, fmin: float) -> tuple[AxisFit, str]:
    """(fit, axis) of an RRF M956 capture: one move's free ringing (axis given, or named in the file's name)."""
    ax = axis or _named_axis(path)
    if ax is None:
        raise RingtuneError("cannot tell which axis this capture measured; give --axis", str(path))
    return identify_decay(data.t, data.axis(ax), ax, str(path), data.rate, max_modes=min(max_modes, 2), fmin=fmin), ax


def _sweep_fits(path, items: list, ax: str, max_modes: int, fmin: float, fmax: float, damping: str) -> list[AxisFit]:
    """The fits of a resonance sweep's spectra on axis ``ax`` (its own column, else the sum)."""
    return [identify_psd(psd.freqs, psd.axis(ax) if psd.psd_x is not None else psd.psd_sum, ax,
                         psd.source or str(path), max_modes, fmin, fmax, damping) for psd in items]


def read_measurement(paths, axis: str | None = None, max_modes: int = 3, fmin: float = SWEEP[0],
                     fmax: float = SWEEP[1], damping: str = "fit") -> Measurement:
    """Read and fit every file (``axis``: the axis of all of them, default from each file)."""
    fits: list[AxisFit] = []
    psds: dict[str, list] = {}
    files: list[dict] = []
    warnings: list[str] = []
    seen: dict[str, str] = {}
    for path in paths:
        data = read_accel(path)
        record = {"name": str(path), "sha256": sha256_of(path)}
        if record["sha256"] in seen:
            warnings.append(f"{path}: the same data as {seen[record['sha256']]}: read once")
            continue
        seen[record["sha256"]] = str(path)
        if isinstance(data, RawAccel) and data.fmt == "m956":
            fit, ax = _free_decay_fit(path, data, axis, max_modes, fmin)
            new = [fit]
            files.append({**record, "axis": ax, "kind": "free decay"})
        else:
            items = to_psd(data)
            ax, warning = _axis(path, items, axis)
            warnings += [warning] if warning else []
            files.append({**record, "axis": ax})
            psds.setdefault(ax, []).extend(items)
            new = _sweep_fits(path, items, ax, max_modes, fmin, fmax, damping)
        fits += new
        warnings += [f"{path}: {w}" for fit in new for w in fit.warnings]
    meas = Measurement(fits, psds, files, warnings)
    meas.warnings += _several_tests_of_an_axis(meas)
    return meas


def _several_tests_of_an_axis(meas: Measurement) -> list[str]:
    """Where one axis has several tests: which one's modes the description takes (the best fit), and
    whether the others' strongest mode lies more than 10 % away from it (not the same machine state)."""
    out = []
    used = meas.by_axis()
    for ax, best in used.items():
        others = [f for f in meas.fits if f.axis == ax and f is not best]
        if not others:
            continue
        f0 = _strongest_freq(best)
        far = [f"{f.source} ({_strongest_freq(f):.1f} Hz)" for f in others if abs(_strongest_freq(f) / f0 - 1) > 0.10]
        out.append(f"{ax.upper()}: {len(others) + 1} tests; the modes are {best.source}'s (the best fit, r² "
                   f"{best.r2:.3f}), Klipper's rule reads them all"
                   + (f"; the strongest mode of {', '.join(far)} is more than 10 % from its {f0:.1f} Hz: "
                      "not the same printer or the same state (belt tension, toolhead)?" if far else ""))
    return out


def _strongest_freq(fit: AxisFit) -> float:
    """Frequency (Hz) of the fit's strongest mode (largest share); NaN without modes."""
    return max(fit.modes, key=lambda m: m.share).freq if fit.modes else float("nan")


def klipper_record(psds: dict[str, list], scv: float = 5.0, version: str = "head") -> dict:
    """``[measurement.klipper]``: Klipper's calibrate_shaper recommendation from the measured spectra
    (the function ``ringtune recommend --accel`` uses), for the axes measured: ``shaper_<ax>``,
    ``freq_<ax>`` (Hz), ``max_accel`` (mm/s², the lower of the axes', as Klipper prints it),
    ``version``, ``scv`` (mm/s, the square-corner velocity the smoothing was computed at)."""
    spectra = {ax: p for ax, p in psds.items() if ax in ("x", "y")}
    if not spectra:
        return {}
    fits, fields = recommend_axes(spectra, "klipper", version, scv)
    rec: dict = {}
    for ax in ("x", "y"):
        if ax in fits:
            rec[f"shaper_{ax}"] = fields[f"shaper_{ax}"]
            rec[f"freq_{ax}"] = fields[f"freq_{ax}"]
    if fields.get("accel"):
        rec["max_accel"] = float(fields["accel"])
    rec["version"] = version
    rec["scv"] = float(scv)
    return rec


def recorded_files(measurement: dict, printer_path: str | Path | None) -> tuple[list[tuple[str, str]], list[str]]:
    """The resonance sweeps a printer description records in ``[measurement]`` that are still here
    and unchanged (free-decay captures, ``kind = "free decay"``, are skipped): ``([(path, axis), …], [missing or changed file, …])``. A recorded name is looked for
    as written (relative to the working folder) and beside the description."""
    found, missing = [], []
    if measurement.get("source") != "accelerometer":     # ripples, a tower: no resonance files
        return found, missing
    folder = Path(printer_path).resolve().parent if printer_path else None
    for rec in measurement.get("files", []):
        if rec.get("kind") == "free decay":      # one move's ringing (M956): not for Klipper's rule
            continue
        name = str(rec.get("name", ""))
        candidates = [Path(name)]
        if folder is not None:
            candidates += [folder / name, folder / Path(name).name]
        hit = next((c for c in candidates if c.is_file() and sha256_of(c) == rec.get("sha256")), None)
        if hit is None:
            missing.append(name)
        else:
            found.append((str(hit), str(rec.get("axis", ""))))
    return found, missing


def resonance_psds(paths: list, axes: str | None = None, note=None) -> tuple[dict[str, list], dict[str, list[str]]]:
    """({axis: [PSD, …]}, {axis: [file, …]}) of resonance-test files; each file's axis from
    ``axes`` (comma-separated, one per file), else its name (a file whose name does not say is
    refused: its columns cannot tell). A file with the same data as an earlier one is read once (said
    through ``note``)."""
    named = _named_axes(axes, len(paths))
    psds: dict[str, list] = {}
    sources: dict[str, list[str]] = {}
    seen: dict[str, str] = {}
    for i, path in enumerate(paths):
        items = to_psd(read_accel(path))
        digest = sha256_of(path)
        if digest in seen:
            if note:
                note(f"{path}: the same data as {seen[digest]}: read once")
            continue
        seen[digest] = str(path)
        ax = named[i] if named else _psd_axis(path)     # said by the name only once the file is new
        psds.setdefault(ax, []).extend(items)
        sources.setdefault(ax, []).append(str(path))
    return psds, sources


def _named_axes(axes: str | None, n_files: int) -> list[str] | None:
    """``axes`` ("x,y,…", one per file) as a list; None when not given."""
    if not axes:
        return None
    named = [a.strip().lower() for a in axes.split(",")]
    if len(named) != n_files or any(a not in ("x", "y") for a in named):
        raise RingtuneError(f"give one axis (x or y) per --accel file ({n_files} files)", "axes")
    return named


def _psd_axis(path) -> str:
    """The axis a resonance file measured, from its name."""
    ax = axis_from_file_name(path)
    if ax == "z":
        raise RingtuneError("the file name says it measured Z; recommend fits X and Y (if it "
                            "measured X or Y, say so with --axes)", str(path))
    if ax is None:
        raise RingtuneError(f"cannot tell which axis this file measured: {UNNAMED_AXIS}; rename it as Klipper "
                            "names it (resonances_x_…, resonances_y_…) or give --axes (one per file)", str(path))
    return ax
