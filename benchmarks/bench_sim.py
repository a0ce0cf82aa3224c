"""Benchmark: whole ``simulate`` cost against the raw ``mujoco.rollout`` of the same steps.

Target (DESIGN.md): simulate ≤ 1.5× raw rollout. Both are measured here in one run on one thread,
on the embedded default printer (with its slip model: two rotor stages on their sinusoidal
magnets, 6 degrees of freedom), for (a) one 2 s motion and (b) a batch of 8 windows of 0.45 s
(about what one evaluation on the built-in test print simulates). The raw baseline is
``rollout.rollout`` on the very model simulate uses (windows packed as replicas of one model), same
initial state and an all-zero control array of the same shape — no control preparation and no
post-processing. "steps" are MuJoCo steps of that model. Also prints the exact LTI backend's cost.

Run: ``/work/venv/bin/python benchmarks/bench_sim.py``
"""

from __future__ import annotations

import time

import numpy as np


def _motion(rng, duration):
    from ringtune.shaping.motion import Motion

    segs, accs = [], []
    total = 0.0
    while total < duration:
        d1, d2 = rng.uniform(0.005, 0.04), rng.uniform(0.0, 0.05)
        a = rng.uniform(1000, 5000) * rng.choice([-1, 1], size=2)
        segs += [d1, d2, d1]
        accs += [a, [0, 0], -a]
        total += 2 * d1 + d2
    t = np.r_[0.0, np.cumsum(segs)]
    return Motion.from_constant_accel(t, np.array(accs))


def _best(fn, repeat=7):
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return min(times)


def _best_pair(f, g, repeat=21):
    """Best-of-n of two functions measured interleaved (robust to load from other processes)."""
    a, b = [], []
    for _ in range(repeat):
        for fn, out in ((f, a), (g, b)):
            t0 = time.perf_counter()
            fn()
            out.append(time.perf_counter() - t0)
    return min(a), min(b)


def main() -> None:
    import mujoco
    from mujoco import rollout

    from ringtune.envs.mujoco_model import TIMESTEP, build_model
    from ringtune.envs.printer import load_printer
    from ringtune.envs.sim import _chunks, _grid, simulate_batch

    rng = np.random.default_rng(1)
    printer = load_printer(None)
    cases = {
        "one 2 s motion": [_motion(rng, 2.0)],
        "8 windows of 0.45 s": [_motion(rng, 0.45) for _ in range(8)],
    }
    ok = True
    for name, motions in cases.items():
        # the same model simulate builds on one thread: the windows as replicas of one model
        nmax = max(_grid(m, TIMESTEP, 0.0) for m in motions)
        chunks = _chunks(len(motions), 1)
        models = [build_model([printer] * len(c), actuators=False) for c in chunks]
        nstate = mujoco.mj_stateSize(models[0], mujoco.mjtState.mjSTATE_FULLPHYSICS)
        init = np.zeros((len(chunks), nstate))
        ctrl = np.zeros((len(chunks), nmax, models[0].nv))          # the drive forces, as simulate gives them
        data = mujoco.MjData(models[0])
        arg = models if len(models) > 1 else models[0]
        simulate_batch(printer, motions, nthread=1)                  # warm the model cache
        forces = int(mujoco.mjtState.mjSTATE_QFRC_APPLIED)
        raw, sim = _best_pair(lambda: rollout.rollout(arg, data, init, ctrl, control_spec=forces),
                              lambda: simulate_batch(printer, motions, nthread=1))
        lti = _best(lambda: simulate_batch(printer, motions, backend="lti"))
        steps = len(chunks) * nmax
        ratio = sim / raw
        ok &= ratio <= 1.5
        print(f"{name}: {steps} steps of {TIMESTEP * 1e3:g} ms RK4 | raw rollout {raw * 1e3:.2f} ms "
              f"({raw / steps * 1e6:.2f} µs/step) | simulate {sim * 1e3:.2f} ms | ratio {ratio:.2f} "
              f"(target ≤ 1.5: {'met' if ratio <= 1.5 else 'NOT met'}) | lti backend {lti * 1e3:.2f} ms")
    print("target simulate ≤ 1.5× raw rollout:", "met" if ok else "NOT met")


if __name__ == "__main__":
    main()
