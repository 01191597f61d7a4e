"""Throughput of the SACPN training loop, in run-steps per second.

One run-step is one environment step of one run (plant step, net step, reward,
actor and critic update).  Measures, in one process and on one core
(BLAS threads pinned to 1):

* the batched trainer (:meth:`mitlc.learn.sacpn.Sacpn.train`) at R = 1 and R = 30;
* what the periodic checkpoint of ``mitlc train`` costs (``--checkpoint-every``);
* a naive baseline: the same algorithm written plainly, a Python loop over runs
  and steps using the library's reference pieces (``Plant.step``,
  ``NetRuntime.step`` and ``.reward`` on markings, the RBF formula per state);

and prints the ratios.  The baseline also checks the fast path: on the same
random numbers its returns match the trainer's.  With ``--violations
permanent|counted`` it measures instead what the violation-aware reward costs
the trainer (its penalty ramp, known penalty value and violation sub-nets):
R = 30 with the option against R = 30 without it, in the same process.

With ``--kernel`` it compares the numpy trial, the exact fused kernel (kernel = numba) and the
fast one (kernel = simd, :mod:`mitlc.learn.sacpn.simd`) in the same process on P1 and P4 at
R = 1 and 30, and prints both kernels' scaling in R on P1 with their ratio. On a 2-core AVX-512
Xeon with another process on the other core (the ratios moved between 0.7x and 2.2x from one run
to the next), the second of two runs printed (run-steps/s; docs/training.md, "The fast kernel")::

    p1 R=1  : numpy 12,767   exact 526,529  simd   711,752  simd / exact 1.35x
    p1 R=30 : numpy 247,146  exact 796,559  simd 1,301,501  simd / exact 1.63x
    p4 R=1  : numpy  9,232   exact 274,735  simd   341,615  simd / exact 1.24x
    p4 R=30 : numpy 156,341  exact 676,915  simd   958,095  simd / exact 1.42x
    scaling, p1: exact, fast, fast / exact
      R=1    :  479,413    417,568   0.87x
      R=10   :  504,717    931,864   1.85x
      R=30   :  668,055  1,182,626   1.77x
      R=100  :  700,392  1,017,068   1.45x
      R=1000 :  575,374    814,643   1.42x

With ``--nested`` it measures the specs with timed obligations (N1..N4, nested intervals) at
R = 30: the numpy trial and the kernel under the standard clock (the obligations' engine in the
kernel), against the kernel on the same spec under ``--clock trial`` (no obligations, a smaller
net), and prints the ratios (the issue's target: standard within 1.5x of trial).

With ``--gym`` it measures SACPN on Gymnasium's environments (the task suite's four specs on
``Pendulum-v1`` and ``MountainCarContinuous-v0``, bench/suite/specs/gym_*.mitl) at R = 8 (a design of
the race) and 30: the numpy trial (the copies stepped by the environment's numpy twin,
:mod:`mitlc.plants.gym_twins`) against the fused kernel (the twin's physics for one copy,
:meth:`~mitlc.plants.gym_twins.Twin.kernel_physics`), and prints the ratio. Both include the
environment's resets (Gymnasium's, a trial's start). On this project's 2-core machine, nothing else
running (2026-12-07)::

    gym_pendulum_spin_response   R=8  : numpy   11,517  kernel  342,705  kernel / numpy  29.8x
    gym_pendulum_spin_response   R=30 : numpy   29,442  kernel  323,018  kernel / numpy  11.0x
    gym_pendulum_swing_up_rest   R=8  : numpy   22,858  kernel  415,423  kernel / numpy  18.2x
    gym_pendulum_swing_up_rest   R=30 : numpy   45,220  kernel  461,408  kernel / numpy  10.2x
    gym_mountain_car_no_wall     R=8  : numpy   19,596  kernel  538,188  kernel / numpy  27.5x
    gym_mountain_car_no_wall     R=30 : numpy   47,403  kernel  575,096  kernel / numpy  12.1x
    gym_mountain_car_left_first  R=8  : numpy   16,152  kernel  463,049  kernel / numpy  28.7x
    gym_mountain_car_left_first  R=30 : numpy   34,964  kernel  368,040  kernel / numpy  10.5x

    python bench/bench_train.py [--problem p1] [--trials 40] [--violations permanent] [--kernel] [--nested] [--gym]
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("MKL_NUM_THREADS", "1")

import argparse  # noqa: E402
import math  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from mitlc.learn.sacpn import Sacpn, SacpnSettings  # noqa: E402
from mitlc.petri.compile import CompileOptions, compile_spec  # noqa: E402
from mitlc.spec.parse import load_spec  # noqa: E402

SPECS = {
    "p1": "p1_swing_up.mitl",
    "p2": "p2_avoid.mitl",
    "p3": "p3_avoid_speed_limit.mitl",
    "p4": "p4_alternate.mitl",
    "p5": "p5_timed_visit.mitl",
    "n1": "n1_reach_in_time.mitl",
    "n2": "n2_hold_up.mitl",
    "n3": "n3_bounded_response.mitl",
    "n4": "n4_recurring_window.mitl",
}


def batched(
    rs, runs: int, trials: int, seed: int = 0, repeats: int = 3, kernel: str = "numpy"
) -> tuple[float, np.ndarray]:
    """Best of ``repeats`` timings (the machine is shared: the best is the least disturbed)."""
    agent = Sacpn(rs, SacpnSettings(kernel=kernel), runs=runs, seed=seed)
    agent.train(2)  # warm up buffers and caches
    best = math.inf
    for _ in range(repeats):
        start = time.perf_counter()
        agent.train(trials)
        best = min(best, time.perf_counter() - start)
    return runs * trials * agent.n_steps / best, agent.returns


def naive(rs, runs: int, trials: int, seed: int = 0) -> tuple[float, np.ndarray]:
    """The same learner, plainly: one run at a time, one step at a time."""
    ref = Sacpn(rs, SacpnSettings(), runs=runs, seed=seed)  # for its settings, generators and constants
    st, plant, rt = ref.settings, ref.plant, ref.runtime
    P, N = rt.n_places, ref.n_steps
    u_max, sigma = ref.u_max, ref.sigma
    # RBF centres and widths, as documented in RbfFeatures
    cq = -math.pi + 2 * math.pi * np.arange(10) / 10
    wq = 2 * math.pi / 10
    lo, hi = -20.0, 20.0
    cv = np.linspace(lo, hi, 10)
    wv = (hi - lo) / 9

    def features(q: float, v: float) -> np.ndarray:
        g = np.exp((np.cos(q - cq) - 1) / wq**2)
        h = np.exp(-((min(max(v, lo), hi) - cv) ** 2) / (2 * wv**2))
        phi = np.outer(g, h).ravel()
        return phi / phi.sum()

    returns = np.zeros((runs, trials))
    start = time.perf_counter()
    for r in range(runs):
        rng = ref.rngs[r]
        xi = np.zeros((P, 100))
        theta = np.zeros((P, 100))
        for trial in range(trials):
            x0 = np.array([[rng.uniform(a, b) for a, b in ref.init_ranges]])
            x0[0, 0] = (x0[0, 0] + math.pi) % (2 * math.pi) - math.pi
            noise = rng.standard_normal(N) * sigma
            x = x0
            M = rt.reset(x)
            e = np.zeros((P, 100))
            for k in range(N):
                m = M[0] / M[0].sum()
                phi = features(x[0, 0], x[0, 1])
                u_raw = m @ xi @ phi
                u_sat = min(max(u_raw, -u_max), u_max)
                a = min(max(u_sat + noise[k], -u_max), u_max)
                du = a - u_sat
                x_next = plant.step(x.copy(), np.array([a]), ref.params)
                M_next = rt.step(M, x_next, (k + 1) * ref.dt)
                reward = float(rt.reward(M, M_next)[0])
                returns[r, trial] += reward
                m_next = M_next[0] / M_next[0].sum()
                phi_next = features(x_next[0, 0], x_next[0, 1])
                delta = reward + st.gamma * (m_next @ theta @ phi_next) - m @ theta @ phi
                step = st.alpha_a * delta * du
                if (u_raw - u_sat) * step > 0:  # anti-wind-up: not further past the bound
                    step = 0.0
                xi += step * np.outer(m, phi)
                e = st.gamma * st.lam * e + np.outer(m, phi)
                theta += st.alpha_c * delta * e
                x, M = x_next, M_next
    wall = time.perf_counter() - start
    return runs * trials * N / wall, returns


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--problem", default="p1", choices=sorted(SPECS))
    ap.add_argument("--trials", type=int, default=40, help="trials timed for the batched trainer")
    ap.add_argument("--naive-trials", type=int, default=4, help="trials timed for the naive loop (3 runs)")
    ap.add_argument("--violations", default="off", choices=("off", "permanent", "counted"))
    ap.add_argument("--kernel", action="store_true", help="numpy trial vs the exact and the fast kernel, P1 and P4")
    ap.add_argument("--nested", action="store_true", help="N1..N4: clock standard (kernel, numpy) vs clock trial")
    ap.add_argument("--gym", action="store_true", help="the suite's Gymnasium specs: numpy trial vs the kernel")
    args = ap.parse_args()
    if args.gym:
        gym(args.trials)
        return
    if args.nested:
        nested(args.trials)
        return
    spec = load_spec(ROOT / "specs" / "pendulum" / SPECS[args.problem])
    rs = compile_spec(spec)
    if args.violations != "off":
        rs_v = compile_spec(spec, CompileOptions.from_spec(spec, violations=args.violations))
        print(
            f"problem {args.problem}: {len(rs.net.places)} places off, {len(rs_v.net.places)} with "
            f"{args.violations}; numpy {np.__version__}, BLAS threads {os.environ['OPENBLAS_NUM_THREADS']}"
        )
        rate_off, _ = batched(rs, 30, args.trials)
        rate_v, _ = batched(rs_v, 30, args.trials)  # the 2 warm-up trials fix a 2-trial ramp: full penalty
        print(f"R=30 off        : {rate_off:12,.0f} run-steps/s")
        print(f"R=30 {args.violations:<11}: {rate_v:12,.0f} run-steps/s")
        print(f"ratio {args.violations} / off: {rate_v / rate_off:5.2f}x")
        return
    if args.kernel:
        kernels(args.trials)
        return
    print(
        f"problem {args.problem}: {len(rs.net.places)} places, {len(rs.net.subnets)} sub-nets, "
        f"numpy {np.__version__}, BLAS threads {os.environ['OPENBLAS_NUM_THREADS']}"
    )
    rate1, _ = batched(rs, 1, args.trials)  # the numpy trial (kernel = numpy)
    rate30, _ = batched(rs, 30, args.trials)
    rate_naive, naive_returns = naive(rs, 3, args.naive_trials)
    # same seed, same random numbers: the fast path must give the naive loop's returns
    check = Sacpn(rs, SacpnSettings(), runs=3, seed=0)
    fast_returns = check.train(args.naive_trials)
    agree = np.abs(fast_returns - naive_returns).max()
    print(f"batched R=1 : {rate1:12,.0f} run-steps/s")
    print(f"batched R=30: {rate30:12,.0f} run-steps/s")
    print(f"naive loop  : {rate_naive:12,.0f} run-steps/s")
    print(
        f"ratio R=30 / naive: {rate30 / rate_naive:6.1f}x   R=1 / naive: {rate1 / rate_naive:5.1f}x   "
        f"R=30 / R=1: {rate30 / rate1:5.1f}x"
    )
    print(f"max |return difference| fast vs naive over {args.naive_trials} trials x 3 runs: {agree:.3g}")
    checkpoint_cost(rs, rate30)


def kernels(trials: int) -> None:
    """The numpy trial, the exact kernel (kernel = numba) and the fast kernel (kernel = simd) in this
    process, P1 and P4 at R = 1 and 30, best of 3 each, and both kernels' scaling in R on P1 with
    their ratio (printed, never asserted)."""
    from mitlc.learn.sacpn.kernel import numba_available

    if not numba_available():
        print("numba is not installed (pip install 'mitlc[fast]'): nothing to compare")
        return
    for problem in ("p1", "p4"):
        rs = compile_spec(load_spec(ROOT / "specs" / "pendulum" / SPECS[problem]))
        for runs in (1, 30):
            first = {}
            for kernel in ("numba", "simd"):
                t0 = time.perf_counter()
                Sacpn(rs, SacpnSettings(kernel=kernel), runs=runs).train(1)  # compiles (once per process)
                first[kernel] = time.perf_counter() - t0
            slow, ret_n = batched(rs, runs, max(2, trials // 10 if runs == 1 else trials // 4))
            exact, _ = batched(rs, runs, trials * 5, kernel="numba")
            fast, _ = batched(rs, runs, trials * 5, kernel="simd")
            print(
                f"{problem} R={runs:<3}: numpy {slow:10,.0f}  exact {exact:10,.0f}  simd {fast:10,.0f} run-steps/s  "
                f"exact / numpy {exact / slow:5.1f}x  simd / exact {fast / exact:4.2f}x  "
                f"(first trial with compile {first['numba']:.1f} s, {first['simd']:.1f} s)"
            )
    rs = compile_spec(load_spec(ROOT / "specs" / "pendulum" / SPECS["p1"]))
    print("scaling, p1 (run-steps/s): exact kernel, fast kernel, fast / exact")
    for runs in (1, 10, 30, 100, 1000):
        exact, _ = batched(rs, runs, max(2, 3000 // runs), kernel="numba")
        fast, _ = batched(rs, runs, max(2, 3000 // runs), kernel="simd")
        print(f"  R={runs:<5}: {exact:12,.0f} {fast:12,.0f}   {fast / exact:4.2f}x")


def nested(trials: int) -> None:
    """N1..N4 at R = 30, best of 3 each: the numpy trial and the kernel under the standard clock (timed
    obligations), and the kernel under ``--clock trial``; the ratios (printed, never asserted)."""
    from mitlc.learn.sacpn.kernel import numba_available

    if not numba_available():
        print("numba is not installed (pip install 'mitlc[fast]'): nothing to compare")
        return
    print("R=30, run-steps/s; standard = timed obligations (nested intervals), trial = --clock trial")
    for problem in ("n1", "n2", "n3", "n4"):
        spec = load_spec(ROOT / "specs" / "pendulum" / SPECS[problem])
        rs_std = compile_spec(spec, CompileOptions.from_spec(spec, clock="standard"))
        rs_trial = compile_spec(spec, CompileOptions.from_spec(spec, clock="trial"))
        assert rs_std.timed and not rs_trial.timed
        for rs in (rs_std, rs_trial):  # compile (once per process and spec) before timing
            Sacpn(rs, SacpnSettings(kernel="numba"), runs=30).train(1)
        slow, _ = batched(rs_std, 30, max(2, trials // 10))
        std, _ = batched(rs_std, 30, trials * 5, kernel="numba")
        trial, _ = batched(rs_trial, 30, trials * 5, kernel="numba")
        print(
            f"{problem}: standard numpy {slow:10,.0f}  standard kernel {std:10,.0f}  trial kernel {trial:10,.0f}  "
            f"kernel / numpy {std / slow:5.1f}x  standard / trial time {trial / std:4.2f}x  "
            f"({len(rs_std.net.places)} places against {len(rs_trial.net.places)})"
        )


GYM_SPECS = (
    "gym_pendulum_spin_response",
    "gym_pendulum_swing_up_rest",
    "gym_mountain_car_no_wall",
    "gym_mountain_car_left_first",
)
"""The task suite's specs on Gymnasium's environments (bench/suite/specs/)."""


def gym(trials: int) -> None:
    """The suite's Gymnasium specs at R = 8 and 30, best of 3 each: the numpy trial (the twin steps the
    copies) and the fused kernel (the twin's physics for one copy); the ratio (printed, never asserted)."""
    from mitlc.learn.sacpn.kernel import numba_available

    if not numba_available():
        print("numba is not installed (pip install 'mitlc[fast]'): nothing to compare")
        return
    print("Gymnasium's environments, run-steps/s: the numpy trial against the fused kernel")
    for name in GYM_SPECS:
        spec = load_spec(ROOT / "bench" / "suite" / "specs" / f"{name}.mitl")
        rs = compile_spec(spec, CompileOptions.from_spec(spec))
        for runs in (8, 30):
            agent = Sacpn(rs, SacpnSettings(kernel="numba"), runs=runs)
            agent.train(1)  # compiles (once per process and spec)
            slow, _ = batched(rs, runs, max(2, trials // 10))
            fast, _ = batched(rs, runs, trials * 5, kernel="numba")
            print(
                f"{name:<28} R={runs:<3}: numpy {slow:8,.0f}  kernel {fast:8,.0f}  kernel / numpy {fast / slow:5.1f}x"
            )


def checkpoint_cost(rs, rate30: float) -> None:
    """What ``mitlc train``'s periodic checkpoint (params.npz and the manifest, atomically and
    fsync'd) costs against R = 30 training, at its default interval and if made every trial."""
    import tempfile

    from mitlc.cli.outputs import OutputSet

    agent = Sacpn(rs, SacpnSettings(), runs=30, seed=0)
    agent.train(2)
    with tempfile.TemporaryDirectory() as tmp, OutputSet(tmp) as outset:
        t0 = time.perf_counter()
        for _ in range(20):
            outset.checkpoint("params.npz", agent.to_bytes(), trial=agent.trial)
        per = (time.perf_counter() - t0) / 20
    trial_s = 30 * agent.n_steps / rate30
    print(
        f"checkpoint: {per * 1e3:.1f} ms; at the default 60 s interval {per / 60 * 100:.4f} % of training, "
        f"after every trial {per / trial_s * 100:.1f} %"
    )


if __name__ == "__main__":
    main()
