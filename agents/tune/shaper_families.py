"""Klipper's parametrised shapers as search families (``mzv(n,t)``: MZV with n impulses over t damped
periods; ``ei(v_tol)``: EI with its tolerated vibration): their Optuna parameters per axis, the
firmware's name for a point of them, and back."""

from __future__ import annotations

from typing import Any

from ringtune.shaping.shapers import parse_name

#: search families of Klipper's parametrised shapers, per shaper flavour that has them
PARAMETRISED = {"klipper": ("mzv(n,t)", "ei(v_tol)")}
MZV_N = (3, 6)
MZV_T_MIN = 0.5
EI_VTOL = (0.01, 0.2)


def mzv_t_max(n: int) -> float:
    """Longest duration (damped periods) searched for ``mzv(n=…)``: just under Klipper's n > 2t + 1."""
    return (n - 1) / 2.0 - 0.01


def suggest_family(trial: Any, family: str, ax: str) -> dict[str, Any]:
    """The parameters of a parametrised family on axis ``ax`` ({} for a plain shaper)."""
    if family == "mzv(n,t)":
        return {f"mzv_n_{ax}": trial.suggest_int(f"mzv_n_{ax}", *MZV_N),
                f"mzv_t_{ax}": trial.suggest_float(f"mzv_t_{ax}", 0.0, 1.0)}
    if family == "ei(v_tol)":
        return {f"ei_vtol_{ax}": trial.suggest_float(f"ei_vtol_{ax}", *EI_VTOL)}
    return {}


def shaper_name(family: str, params: dict[str, Any], ax: str) -> str:
    """The firmware's shaper name of a search family and its parameters: ``mzv(n=5,t=1.1)``,
    ``ei(v_tol=0.08)``, or the plain name (t to 0.01 period, v_tol to 0.005, as a user would type)."""
    if family == "mzv(n,t)":
        n = int(params[f"mzv_n_{ax}"])
        t = MZV_T_MIN + float(params[f"mzv_t_{ax}"]) * (mzv_t_max(n) - MZV_T_MIN)
        return f"mzv(n={n},t={round(t, 2):g})"
    if family == "ei(v_tol)":
        return f"ei(v_tol={_q(params[f'ei_vtol_{ax}'], 0.005):g})"
    return family


def family_params(name: str, ax: str) -> tuple[str, dict[str, Any]]:
    """Inverse of :func:`shaper_name`: (family, parameters) of a configuration's shaper name."""
    base, params = parse_name(name)
    if base == "mzv" and params:
        n = int(params.get("n", 3))
        t = float(params.get("t", 0.75))
        return "mzv(n,t)", {f"mzv_n_{ax}": n, f"mzv_t_{ax}": (t - MZV_T_MIN) / (mzv_t_max(n) - MZV_T_MIN)}
    if base == "ei" and params:
        return "ei(v_tol)", {f"ei_vtol_{ax}": float(params.get("v_tol", 0.05))}
    return name, {}


def _q(value: float, step: float) -> float:
    return round(round(float(value) / step) * step, 6)
