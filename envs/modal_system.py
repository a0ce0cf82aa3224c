"""The printer's linear mechanics as matrices: ``M q̈ + C q̇ + K q = −M·B·a_cmd`` (model units mm,
kg, s). Built by :func:`ringtune.envs.mujoco_model.linear_system` (rigid motors) or
:func:`ringtune.envs.rotor.slip_system` (slip model); read by the MuJoCo model builder, the
simulator and the exact linear reference (:mod:`ringtune.envs.lti`)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass
class LinearSystem:
    """``M q̈ + C q̇ + K q = −M·B·a_cmd``; q (n,) mm relative to the commanded position.

    Attributes:
        names: body names, one per modal coordinate.
        axis: (n,) 0 for X, 1 for Y.
        mass: (n,) modal masses, kg.
        share: (n,) nozzle weight of each coordinate on its axis.
        K, C: (n, n) stiffness (N/m) and damping (kg/s) matrices.
        joint_stiffness, joint_damping: (n,) what sits on each slide joint.
        belts: CoreXY belt tendons as (name, {coordinate index: coef}, stiffness).
        kinematics: "cartesian" or "corexy".
        drive: (n, 2) or None: commanded acceleration weights per coordinate (default one-hot of
            ``axis``); a CoreXY rotor A is driven by a_x + a_y.
        nozzle_w: (n, 2) or None: nozzle deviation = q @ nozzle_w (default one-hot·share).
        scale: (n,) or None: mm of the coordinate per MuJoCo joint unit (1 for slides; λ/2π for a
            rotor hinge).
        rotors: :class:`ringtune.envs.rotor.Rotor` stages (slip model), empty otherwise.
        springs: slip model: every spring/damper as (name, {index: coef}, stiffness, damping).
    """

    names: list[str]
    axis: np.ndarray
    mass: np.ndarray
    share: np.ndarray
    K: np.ndarray
    C: np.ndarray
    joint_stiffness: np.ndarray
    joint_damping: np.ndarray
    belts: list = field(default_factory=list)
    kinematics: str = "cartesian"
    drive: np.ndarray | None = None
    nozzle_w: np.ndarray | None = None
    scale: np.ndarray | None = None
    rotors: list = field(default_factory=list)
    springs: list = field(default_factory=list)

    @property
    def n(self) -> int:
        return len(self.names)

    @property
    def B(self) -> np.ndarray:
        """(n, 2) which commanded acceleration (x, y) drives each coordinate."""
        if self.drive is not None:
            return self.drive
        b = np.zeros((self.n, 2))
        b[np.arange(self.n), self.axis] = 1.0
        return b

    @property
    def W(self) -> np.ndarray:
        """(n, 2) nozzle weights: nozzle deviation (x, y) = q @ W."""
        if self.nozzle_w is not None:
            return self.nozzle_w
        w = np.zeros((self.n, 2))
        w[np.arange(self.n), self.axis] = self.share
        return w

    def state_matrices(self) -> tuple[np.ndarray, np.ndarray]:
        """Continuous state space ``ẋ = A x + G a_cmd`` with x = [q, q̇] (2n,), a_cmd (2,)."""
        n = self.n
        minv = 1.0 / self.mass
        A = np.zeros((2 * n, 2 * n))
        A[:n, n:] = np.eye(n)
        A[n:, :n] = -minv[:, None] * self.K
        A[n:, n:] = -minv[:, None] * self.C
        G = np.zeros((2 * n, 2))
        G[n:] = -self.B
        return A, G

    def qacc(self, q: np.ndarray, qd: np.ndarray, a_cmd: np.ndarray, nonlinear: bool = False) -> np.ndarray:
        """(m, n) relative accelerations from states (m, n) and commanded accelerations (m, 2).
        ``nonlinear``: rotors feel their sinusoidal magnetic force (the MuJoCo slip model) instead
        of its linearisation."""
        f = -(q @ self.K.T + qd @ self.C.T)
        if nonlinear:
            for r in self.rotors:
                e = q[:, r.index]
                f[:, r.index] += r.stiffness * e - r.peak * np.sin(e * (2.0 * np.pi / r.cycle))
        return f / self.mass - a_cmd @ self.B.T

    def static_deflection(self, a_cmd: np.ndarray) -> np.ndarray:
        """q (n,) at rest under a constant commanded acceleration (the lag of seeds/002)."""
        return np.linalg.solve(self.K, -self.mass * (self.B @ np.asarray(a_cmd, float)))
