"""The printer as a linear mechanical system and as a MuJoCo model generated from it.

Formulation (why it is built this way):

- **Frame of reference** (seeds/002): the stepper follows the commanded position until it slips,
  so every moving part is described *relative to the commanded position*. In that non-inertial
  frame the commanded acceleration ``a_cmd`` acts as a fictitious force ``−m·a_cmd`` on every mass.
  Each mode is a body on a slide joint (coordinate q, mm) with a spring and damper to the
  commanded position; a motor actuator on each body (gear = its mass, control = −a_cmd) applies
  ``−m·a_cmd``. This is the base-excitation ODE
  ``q̈ + 2ζω q̇ + ω² q = −a_cmd`` exactly, which is what makes acceptance 1 and 2 hold to the
  integrator's accuracy; a stiff position servo carriage would need a far smaller timestep and adds a
  velocity-proportional following error (../shared/reference/ecosystem.md §4).
- **Several modes per axis** (belt stretch, toolhead rocking…) are modal bodies side by side; the
  nozzle deviation on an axis is ``Σ share_i·q_i``; each body carries its modal mass
  ``mass_share_i · axis mass`` so the force through the belts is ``Σ m_i (a_cmd + q̈_i)``.
- **Cartesian**: X modes belong to the toolhead, Y modes to the bed, whose mass includes the print.
  **CoreXZ** is the same mechanics in the XY plane (Z is still while a layer prints: A and B turn
  together with X; Y is a bed slinger's); only the motors differ (:meth:`Printer.drive_motors`).
  The nozzle relative to the print is ``commanded + deviation`` on both axes.
- **CoreXY**: the first X and first Y mode are coupled through the two belts, fixed tendons
  ``A = u + w`` and ``B = u − w`` with stiffness ``k_A``, ``k_B`` (u, w: X and Y deviations). The
  stiffness matrix is ``[[k_A + k_B + r_x, k_A − k_B], [k_A − k_B, k_A + k_B + r_y]]``; the residual
  joint stiffnesses r_x, r_y ≥ 0 (frame, pulleys) put matched belts exactly on the measured
  frequencies. Unequal belts give an off-diagonal term, so a pure X move excites Y.
- **Motor force and step loss**: the force each motor must give is the belt force that accelerates
  the masses plus its rotor's inertia and friction (computed exactly from the state in
  :mod:`ringtune.envs.sim`); step loss is that force exceeding the motor's force at the motor's
  speed (:meth:`MotorModel.max_force`).
- **Slip model** (default whenever the motor can carry the described modes; ``[motor] slip``):
  each motor gets a rotor coordinate held to the commanded electrical position by the stepper's
  real torque–angle curve ``−F_hold·sin(2π e/λ)`` (λ = 4 full steps), so a motor asked for more
  than F_hold *falls behind and skips whole electrical cycles* in MuJoCo, which no linear model
  can show; the modes hang off the rotors with their springs re-solved in series so that the
  described frequencies, shares and damping hold exactly (the nozzle's linear response is the
  rigid-motor model's). The exact LTI reference integrates the linearised twin (spring
  k_m = F_hold·2π/λ). Step loss is then also flagged when a rotor lags a full step (the torque
  peak). Formulation, MuJoCo realisation (rotor pendulum, sparse damper tendons) and limits in
  :mod:`ringtune.envs.rotor`. The clamp is the standstill holding force; the fall of the
  available force with speed remains a detection criterion only.
- **Accelerometer**: optional MuJoCo ``accelerometer`` sensor on the toolhead body (first X mode;
  it reads that body's acceleration relative to the commanded frame).
  The simulator reports the head's absolute acceleration computed exactly from the state
  (``a_cmd + Σ share·q̈``) because rollout sensordata lag one step and cost time.

Units inside the model: mm, s, kg (so forces are kg·mm/s² = mN; stiffness kg/s² = N/m).
"""

from __future__ import annotations

import mujoco
import numpy as np

from ringtune.envs.modal_system import LinearSystem
from ringtune.envs.printer_model import Printer
from ringtune.envs.rotor import slip_system
from ringtune.shaping.errors import RingtuneError

#: the model's gravity (mm/s², along −z) when it holds rotor pendulums: it drives only their
#: sinusoidal magnetic torque (every other joint slides horizontally). Large, so that the pendulum
#: arm ρ = F_hold·(λ/2π)/(m_r·G) stays far inside the rotor's radius of gyration λ/2π.
_MAGNET_G = 1.0e9

#: default integrator and timestep: RK4 at 0.5 ms is within 0.12 % RMS at 120 Hz (ecosystem.md §4)
INTEGRATOR = "RK4"
TIMESTEP = 0.0005


#: solved slip systems (or False: infeasible) by printer description; the series solve costs ms
_SLIP_CACHE: dict = {}


def linear_system(printer: Printer) -> LinearSystem:
    """The printer's linear mechanics (modes after print mass), as used by both backends; with
    ``[motor] slip = true`` the linearised slip model of :mod:`ringtune.envs.rotor`."""
    slips = {mo.slip for _n, mo, _d in printer.drive_motors()}
    if False not in slips:
        key = _printer_key(printer)
        got = _SLIP_CACHE.get(key)
        if got is None:
            try:
                got = slip_system(printer)
            except RingtuneError:
                if True in slips:
                    raise
                got = False                      # the motor cannot carry the modes: rigid motor
            if len(_SLIP_CACHE) > 256:
                _SLIP_CACHE.clear()
            _SLIP_CACHE[key] = got
        if got is not False:
            return got
    names, axis, mass, share, k, c = [], [], [], [], [], []
    for ai, ax in enumerate(("x", "y")):
        total = printer.moving_mass(ax)
        for j, m in enumerate(printer.effective_modes(ax)):
            mi = max(m.mass_fraction, 1e-6) * total
            names.append(f"{ax}{j}")
            axis.append(ai)
            mass.append(mi)
            share.append(m.share)
            k.append(mi * m.omega ** 2)
            c.append(2.0 * m.damping * m.omega * mi)
    K = np.diag(np.array(k, float))
    C = np.diag(np.array(c, float))
    js = np.array(k, float)
    belts = []
    if printer.kinematics == "corexy":
        ix, iy = names.index("x0"), names.index("y0")
        ka, kb = printer.belt_stiffnesses()
        js[ix] = K[ix, ix] - (ka + kb)
        js[iy] = K[iy, iy] - (ka + kb)
        K[ix, iy] = K[iy, ix] = ka - kb
        belts = [("belt_a", {ix: 1.0, iy: 1.0}, ka), ("belt_b", {ix: 1.0, iy: -1.0}, kb)]
    return LinearSystem(names, np.array(axis, int), np.array(mass, float), np.array(share, float),
                        K, C, js, np.diag(C).copy(), belts, printer.kinematics)


#: the slide direction of each axis's coordinates (x, y)
_AXIS_DIRS = ("1 0 0", "0 1 0")


def _body(sysm, i: int, name: str, y: float, rotor, grav: float, site: str) -> str:
    """MJCF body of modal coordinate ``i``: a slide on its axis, or a rotor's hinge (a pendulum under
    the model's gravity ``grav``: torque −m_r·G·ρ·sin φ = −F_hold·(λ/2π)·sin φ, envs.rotor)."""
    if rotor is None:
        return (f'<body name="{name}" pos="0 {y:g} 0">'
                f'<inertial pos="0 0 0" mass="{sysm.mass[i]:.12g}" diaginertia="1e-6 1e-6 1e-6"/>'
                f'<joint name="q_{name}" type="slide" axis="{_AXIS_DIRS[sysm.axis[i]]}" '
                f'stiffness="{sysm.joint_stiffness[i]:.12g}" damping="{sysm.joint_damping[i]:.12g}"/>'
                f'{site}</body>')
    rho = rotor.peak * rotor.scale / (rotor.mass * grav)
    inertia = rotor.mass * (rotor.scale ** 2 - rho ** 2)
    return (f'<body name="{name}" pos="0 {y:g} 0">'
            f'<inertial pos="0 0 {-rho:.12g}" mass="{rotor.mass:.12g}" '
            f'diaginertia="{inertia:.12g} {inertia:.12g} {inertia:.12g}"/>'
            f'<joint name="q_{name}" type="hinge" axis="0 1 0" '
            f'damping="{sysm.joint_damping[i] * rotor.scale ** 2:.12g}"/></body>')


def _tendons(sysm, sfx: str, scale) -> list[str]:
    """MJCF tendons of one replica: CoreXY's belts, then the motors' springs (scaled coordinates)."""
    out = []
    for bname, coefs, k in sysm.belts:
        joints = "".join(f'<joint joint="q_{sysm.names[i]}{sfx}" coef="{c:g}"/>' for i, c in coefs.items())
        out.append(f'<fixed name="{bname}{sfx}" stiffness="{k:.12g}">{joints}</fixed>')
    for bname, coefs, k, c in sysm.springs:
        joints = "".join(f'<joint joint="q_{sysm.names[i]}{sfx}" coef="{cf * scale[i]:.12g}"/>'
                         for i, cf in coefs.items())
        out.append(f'<fixed name="{bname}{sfx}" stiffness="{k:.12g}" damping="{c:.12g}" '
                   f'springlength="0">{joints}</fixed>')
    return out


def _replica(sysm, sfx: str, first_row: int, grav: float, accelerometer: bool) -> tuple[list, list, list]:
    """(bodies, tendons, motors) of one printer's replica, its bodies from row ``first_row`` on."""
    rot = {r.index: r for r in sysm.rotors}
    scale = sysm.scale if sysm.scale is not None else np.ones(sysm.n)
    bodies, motors, gains = [], [], drive_gains(sysm)
    for i, name in enumerate(sysm.names):
        site = f'<site name="toolhead{sfx}" size="2"/>' if accelerometer and name == "x0" else ""
        bodies.append(_body(sysm, i, f"{name}{sfx}", 20.0 * (first_row + i), rot.get(i), grav, site))
        motors.append(f'<motor name="drive_{name}{sfx}" joint="q_{name}{sfx}" '
                      f'gear="{float(gains[i])!r}" ctrllimited="false"/>')
    return bodies, _tendons(sysm, sfx, scale), motors


def drive_gains(sysm: LinearSystem) -> np.ndarray:
    """(n,) force per unit control of each coordinate's drive (its modal mass, per joint unit; the
    motor's gear), as the MJCF gives it (12 significant digits): the generalised force
    ``gain · (−a_cmd)`` is the fictitious force ``−m·a_cmd`` of the commanded frame."""
    scale = sysm.scale if sysm.scale is not None else np.ones(sysm.n)
    return np.array([float(f"{m * s:.12g}") for m, s in zip(sysm.mass, scale)])


def build_mjcf(printer: Printer | list, timestep: float = TIMESTEP, integrator: str = INTEGRATOR,
               accelerometer: bool = False, actuators: bool = True) -> str:
    """MJCF text: one slide-jointed body per modal coordinate, belt tendons for CoreXY, one motor
    per coordinate (gear = its modal mass; control = −a_cmd of its axis, mm/s²) and optionally an
    accelerometer on the toolhead.

    ``actuators=False`` leaves the motors out: the drive is then given as the generalised force
    itself (``qfrc_applied`` = :func:`drive_gains` · control, what the motors would apply, to the
    bit), which spares MuJoCo its actuation stage (about 8 % of a rollout's time).

    Given a list of printers, the model holds one independent replica per printer (names suffixed
    ``_r<k>``) in coordinate order: a single rollout then advances many windows at once, which
    amortises MuJoCo's fixed per-step cost (about 3× cheaper per window at 8 replicas)."""
    printers = printer if isinstance(printer, (list, tuple)) else [printer]
    systems = [linear_system(pr) for pr in printers]
    sfxs = [f"_r{r}" if len(printers) > 1 else "" for r in range(len(printers))]
    # magnet gravity: large enough that every pendulum arm is ≤ λ/2π / 4
    rotors = [r for s_ in systems for r in s_.rotors]
    grav = max([_MAGNET_G] + [4.0 * r.peak / r.mass for r in rotors])
    gravity = bool(rotors)
    bodies, tendons, motors = [], [], []
    row = 0
    for sysm, sfx in zip(systems, sfxs):
        b, t, m = _replica(sysm, sfx, row, grav, accelerometer)
        bodies, tendons, motors, row = bodies + b, tendons + t, motors + m, row + len(b)
    sensors = ""
    if accelerometer:
        sensors = "<sensor>" + "".join(f'<accelerometer name="accel{x}" site="toolhead{x}"/>'
                                       for x in sfxs) + "</sensor>"
    name = _xml_escape(printers[0].name) + (f" x{len(printers)}" if len(printers) > 1 else "")
    return (
        f'<mujoco model="{name}">'
        '<compiler angle="radian"/>'
        f'<option timestep="{timestep:.12g}" integrator="{integrator}" '
        f'gravity="0 0 {-grav if gravity else 0.0:.12g}">'
        f'<flag contact="disable" constraint="disable" energy="disable" '
        f'gravity="{"enable" if gravity else "disable"}" '
        'warmstart="disable" filterparent="disable" midphase="disable" nativeccd="disable" '
        'island="disable"/></option>'
        f'<worldbody>{"".join(bodies)}</worldbody>'
        + (f'<tendon>{"".join(tendons)}</tendon>' if tendons else "")
        + (f'<actuator>{"".join(motors)}</actuator>' if actuators else "") + f'{sensors}</mujoco>')


def _xml_escape(s: str) -> str:
    return s.replace("&", "&amp;").replace("<", "&lt;").replace('"', "&quot;")


_MODEL_CACHE: dict = {}


def build_model(printer: Printer | list, timestep: float = TIMESTEP, integrator: str = INTEGRATOR,
                accelerometer: bool = False, actuators: bool = True):
    """Compiled ``mujoco.MjModel`` of one printer or of replicas of several (see :func:`build_mjcf`),
    cached by descriptions, timestep, integrator and options."""
    printers = tuple(printer) if isinstance(printer, (list, tuple)) else (printer,)
    seen: dict = {}
    key = (tuple(seen.setdefault(id(p), _printer_key(p)) if id(p) not in seen else seen[id(p)]
                 for p in printers), float(timestep), integrator, bool(accelerometer), bool(actuators))
    model = _MODEL_CACHE.get(key)
    if model is None:
        arg = list(printers) if len(printers) > 1 else printers[0]
        model = mujoco.MjModel.from_xml_string(build_mjcf(arg, timestep, integrator, accelerometer, actuators))
        if len(_MODEL_CACHE) > 64:
            _MODEL_CACHE.clear()
        _MODEL_CACHE[key] = model
    return model


def _printer_key(printer: Printer) -> str:
    return printer.to_toml()
