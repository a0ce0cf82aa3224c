"""Force at the belt against speed of a two-phase hybrid stepper on a current-chopper driver, from
the datasheet constants (:class:`ringtune.envs.motors.MotorConstants`) and the drive.

Units: SI inside (Ω, H, N·m, A, V, rad/s); belt speeds in mm/s, forces in N, ``rotation_distance``
in mm of belt per motor revolution (Klipper's key).

Derivation
----------
**Machine.** A hybrid stepper with ``N`` full steps per revolution is a non-salient permanent-magnet
synchronous machine with ``p = N/4`` pole pairs (200 steps: 50): one electrical cycle is 4 full
steps, so the electrical angle is θ_e = p·θ and ω_e = (N/4)·ω (ω mechanical, rad/s). Each phase
(resistance R, inductance L) sees the back-EMF e_a = −K ω sin θ_e, e_b = K ω cos θ_e and the
torque is T = K(−i_a sin θ_e + i_b cos θ_e). Power balance (e·i = T·ω) makes the peak back-EMF
constant (V·s/rad) and the torque constant (N·m per A of *peak* phase current) the same number K.

**K from the datasheet.** Holding torque T_h is specified with both phases on at the rated current
I_r; the two phase torques are 90° apart, so T_h = √2·K·I_r and

    K = T_h / (√2·I_r)             [N·m/A_peak = V·s/rad_peak]

Its RMS form K/√2 = T_h/(2·I_r) is exactly the back-EMF constant Klipper's autotune plugin uses
(``holding_torque / (2·max_current)``, V·s/rad): the two conventions agree.

**Drive current.** ``run_current`` I_run is RMS (Klipper ``run_current``, M906), so the sine
microstepping peak per phase is √2·I_run; at standstill T_0 = K·√2·I_run = T_h·I_run/I_r (run current
equal to the rated current gives the holding torque: same copper loss as two phases on at I_r). Iron
saturates above that: the current credited for torque is capped at √2·I_r (conservative).

**Voltage limit (phasor form).** In steady state at ω the phase is R + jX (X = ω_e·L, |Z|² = R² + X²)
in series with the back-EMF phasor E = K·ω, taken along the real (torque) axis; the driver's H-bridge
can put at most the supply V (peak, sine PWM) across the phase, and its chopper holds the current
amplitude at most I_p = √2·I_run. The current phasor I is therefore confined to two discs:

    |I| ≤ I_p                       (current regulation)
    |Z·I + E| ≤ V  ⇔  |I − c| ≤ V/|Z|,   c = −E/Z        (voltage)

and the torque is K·Re(I) (only the component in phase with the back-EMF does work). An open-loop
stepper's rotor finds its load angle by itself, so the pull-out torque is the largest K·Re(I) over
the intersection: the rightmost point of the current disc (I_p, with current exactly in phase) when
the voltage allows it, else the rightmost point of the voltage disc, Re = (V·|Z| − E·R)/|Z|² (the
classical pull-out torque of a voltage-fed synchronous machine), when that current is within I_p,
else the better of the two points where the circles cross. This is the current- and voltage-limit
circle analysis of PM synchronous drives (Morimoto et al., IEEE Trans. Ind. Appl. 26(5), 1990) applied
to a stepper, the pull-out characteristic of P. Acarnley, *Stepping Motors: a guide to theory and
practice*, ch. 4. Consequences: a higher voltage enlarges only the voltage disc (never less torque);
the torque is flat at K·I_p up to the corner speed where the in-phase current stops fitting, then
falls, like 1/ω at high speed.

**At the belt.** Pulley radius r = rotation_distance/2π (mm → m), ω = v/r, F = T/r.

Left out (state of the art for a planning model, and all of them lower the real force a little):
detent torque, iron and eddy losses, mid-band resonance, the chopper's dead time and the H-bridge's
voltage drop. ``voltage`` is the supply; a square-wave (full-step) drive would reach 4/π more.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ringtune.envs.motors import MotorConstants

#: supply voltage (V) assumed when none is given: the common 24 V printer supply
DEFAULT_VOLTAGE = 24.0
#: belt mm per motor revolution assumed when neither it nor steps_per_mm is given: GT2 belt, 20 teeth
DEFAULT_ROTATION_DISTANCE = 40.0


def default_run_current(rated_current: float) -> float:
    """A RMS assumed when none is given: rated/√2, the peak of the sine equals the rated current
    (the usual advice for Klipper's run_current)."""
    return rated_current / math.sqrt(2.0)


@dataclass(frozen=True)
class StepperDrive:
    """A motor on its driver and pulley: constants + run current (A RMS), supply voltage (V),
    rotation distance (mm of belt per revolution)."""

    motor: MotorConstants
    run_current: float
    voltage: float
    rotation_distance: float

    # -- constants ---------------------------------------------------------------------------------
    @property
    def torque_constant(self) -> float:
        """K, N·m per A of peak phase current (= peak back-EMF constant, V·s/rad)."""
        return self.motor.holding_torque / (math.sqrt(2.0) * self.motor.rated_current)

    @property
    def back_emf_rms(self) -> float:
        """K/√2 = holding_torque/(2·rated_current), V·s/rad RMS per phase (Klipper autotune's ke)."""
        return self.motor.holding_torque / (2.0 * self.motor.rated_current)

    @property
    def pole_pairs(self) -> float:
        """Electrical cycles per revolution, steps_per_revolution/4."""
        return self.motor.steps_per_revolution / 4.0

    @property
    def radius(self) -> float:
        """Pulley pitch radius, m."""
        return self.rotation_distance * 1e-3 / (2.0 * math.pi)

    @property
    def peak_current(self) -> float:
        """A: the driver's peak phase current √2·run_current."""
        return math.sqrt(2.0) * self.run_current

    # -- curves ------------------------------------------------------------------------------------
    def torque(self, omega: np.ndarray | float) -> np.ndarray:
        """Pull-out torque (N·m) at mechanical speed ``omega`` (rad/s, sign ignored); see the module
        docstring for the derivation."""
        w = np.abs(np.asarray(omega, dtype=float))
        K, R, L, V = self.torque_constant, self.motor.resistance, self.motor.inductance, self.voltage
        ip = self.peak_current
        E = K * w
        X = self.pole_pairs * w * L
        Z2 = R * R + X * X
        Z = np.sqrt(Z2)
        # 1. the full current in phase with the back-EMF fits under the voltage
        in_phase = (R * ip + E) ** 2 + (X * ip) ** 2 <= V * V
        # 2. the rightmost point of the voltage disc, if within the current disc
        re_v = (V * Z - E * R) / Z2
        im_v = E * X / Z2
        volt = re_v * re_v + im_v * im_v <= ip * ip
        # 3. the circles |I| = ip and |I - c| = V/|Z| cross (c = -E/Z, |c| = E/|Z|)
        d = E / Z
        rho = V / Z
        with np.errstate(divide="ignore", invalid="ignore"):
            a = (ip * ip - rho * rho + d * d) / (2.0 * d)
            h = np.sqrt(np.maximum(ip * ip - a * a, 0.0))
            cross = np.where(ip * ip - a * a >= 0.0, (-a * R + h * X) / Z, 0.0)
        iq = np.where(in_phase, ip, np.where(volt, re_v, cross))
        iq = np.minimum(np.maximum(np.nan_to_num(iq), 0.0), math.sqrt(2.0) * self.motor.rated_current)
        return K * iq

    def force(self, speed: np.ndarray | float) -> np.ndarray:
        """Force (N) at the belt at belt speed ``speed`` (mm/s, sign ignored)."""
        v = np.abs(np.asarray(speed, dtype=float))
        return self.torque(v * 1e-3 / self.radius) / self.radius

    @property
    def standstill_force(self) -> float:
        """N at the belt at low speed: the holding force at the run current (the rotor's F_hold)."""
        return float(self.force(0.0))

    def speed_at_fraction(self, fraction: float) -> float:
        """Belt speed (mm/s) at which the force has fallen to ``fraction`` of the standstill force
        (the curve is non-increasing: first crossing on a log grid, then bisection); inf if never."""
        f0 = self.standstill_force
        target = f0 * fraction * (1.0 - 1e-9)
        grid = np.concatenate([[0.0], np.geomspace(1e-2, 1e7, 361)])
        below = np.flatnonzero(self.force(grid) <= target)
        if not len(below):
            return math.inf
        if below[0] == 0:
            return 0.0
        lo, hi = float(grid[below[0] - 1]), float(grid[below[0]])
        for _ in range(60):
            mid = 0.5 * (lo + hi)
            if float(self.force(mid)) > target:
                lo = mid
            else:
                hi = mid
        return 0.5 * (lo + hi)

    @property
    def corner_speed(self) -> float:
        """mm/s up to which the full force is available. With the run current at most the rated
        one, the full current fits in phase while (R·I_p + K·ω)² + (p·L·ω·I_p)² ≤ V²: the positive
        root of that quadratic in ω (0 when even standstill cannot reach it); above, by search."""
        if self.run_current > self.motor.rated_current:
            return self.speed_at_fraction(1.0)
        K, R, ip, V = self.torque_constant, self.motor.resistance, self.peak_current, self.voltage
        a = K * K + (self.pole_pairs * self.motor.inductance * ip) ** 2
        b = 2.0 * R * ip * K
        c = (R * ip) ** 2 - V * V
        if c >= 0.0:
            return 0.0
        w = (-b + math.sqrt(b * b - 4.0 * a * c)) / (2.0 * a)
        return w * self.radius * 1e3

    @property
    def half_force_speed(self) -> float:
        """mm/s at which the force has fallen to half the standstill force."""
        return self.speed_at_fraction(0.5)
