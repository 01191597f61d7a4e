"""A Stable-Baselines3 model judged as a SACPN policy is: mitlc.gym.Sb3Policy (load_policy's interface),
``mitlc simulate --policy model.zip --spec SPEC`` and its traces read by ``mitlc check``.

The models train for a few hundred steps on a registered environment (mitlc/Pendulum-v0); what is
asserted is that simulate's rollouts, verdicts and returns are the environment's own episodes from the
same starts, whatever the model learned."""

from __future__ import annotations

import re
import sys
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from mitlc.cli import main

SPEC = """plant pendulum(u_max = 3)
init q in [-0.25, 0.25], qdot = 0
horizon 1
prop kappa = abs(q) < 0.3
formula G[0,0.2] kappa
"""
"""Starts near the top: the pendulum stays in kappa for the first 0.2 s from some, not from others."""

LINE = re.compile(
    r"rollout +(\d+) \(run +0, q=(\S+), qdot=(\S+)\): (satisfied|VIOLATED at t=(\S+) s \((.+)\)); "
    r"robustness (\S+); return (\S+)$"
)


def sb3():
    pytest.importorskip("stable_baselines3", reason="needs Stable-Baselines3 and PyTorch: pip install 'mitlc[sb3]'")
    return pytest.importorskip("gymnasium")


@pytest.fixture(scope="module")
def models(tmp_path_factory) -> dict[str, Path]:
    """A SAC model (flat observations) and a PPO model (Dict observations), each trained briefly on
    mitlc/Pendulum-v0 with SPEC and saved as .zip."""
    gym = sb3()
    import torch
    from stable_baselines3 import PPO, SAC

    import mitlc.gym  # noqa: F401 - registers the environments

    torch.set_num_threads(1)
    d = tmp_path_factory.mktemp("sb3")
    (d / "spec.mitl").write_text(SPEC)
    spec = str(d / "spec.mitl")
    sac_env = gym.make("mitlc/Pendulum-v0", spec=spec, marking_obs="box", verdict="off")
    sac = SAC("MlpPolicy", sac_env, seed=0, device="cpu", learning_starts=100, batch_size=64)
    sac.learn(300)
    sac.save(d / "sac.zip")
    ppo_env = gym.make("mitlc/Pendulum-v0", spec=spec, verdict="off")
    ppo = PPO("MultiInputPolicy", ppo_env, seed=0, device="cpu", n_steps=128, batch_size=64, n_epochs=2)
    ppo.learn(256)
    ppo.save(d / "ppo.zip")
    return {"spec": d / "spec.mitl", "sac": d / "sac.zip", "ppo": d / "ppo.zip"}


def episode(model_path: Path, spec: Path, x0: np.ndarray, marking_obs: str):
    """The model's deterministic episode in the environment from ``x0``: states, inputs, return, last info."""
    gym = sb3()
    from mitlc.gym import sb3_algorithm

    model = sb3_algorithm(model_path).load(model_path, device="cpu")
    env = gym.make("mitlc/Pendulum-v0", spec=str(spec), marking_obs=marking_obs, verdict="end")
    obs, _ = env.reset(seed=0, options={"x0": x0})
    states, inputs, ret, done = [env.unwrapped.trace[0]], [], 0.0, False
    while not done:
        a, _ = model.predict(obs, deterministic=True)
        obs, r, term, trunc, info = env.step(a)
        states.append(env.unwrapped.trace[-1])
        inputs.append(float(np.clip(a[0], -3, 3)))
        ret += r
        done = term or trunc
    return np.array(states), np.array(inputs), ret, info


@pytest.mark.parametrize("name, marking_obs", [("sac", "box"), ("ppo", "dict")])
def test_sb3policy_rolls_out_the_environments_episodes(models, name: str, marking_obs: str) -> None:
    """The Policy interface on a model: its rollouts are the environment's episodes to the bit, in a
    batch too, and its reward the environment's."""
    sb3()
    from mitlc.gym import load_sb3
    from mitlc.learn.policy import Policy

    pol = load_sb3(models[name], models["spec"])
    assert isinstance(pol, Policy) and pol.runs == 1 and pol.dt == 0.03 and pol.marking_obs == marking_obs
    assert type(pol.model).__name__ == name.upper()
    x0 = np.array([[0.1, 0.0], [-0.2, 0.0], [0.24, 0.0]])
    ro = pol.rollout(x0)
    assert ro.states.shape == (3, 34, 2) and ro.actions.shape == (3, 33)
    for b in range(3):
        states, inputs, ret, _ = episode(models[name], models["spec"], x0[b], marking_obs)
        np.testing.assert_array_equal(ro.states[b], states)
        np.testing.assert_array_equal(ro.actions[b], inputs)
        assert ro.returns[b] == ret
    # step by step, as load_policy's policies are used
    m = pol.reset(x0[:1])
    assert pol.place_names == ("p_tau<=0.2", "p_tau>0.2", "p_kappa", "p_not_kappa")
    assert m.tolist() == [[1, 0, 1, 0]]  # before 0.2 s, in kappa
    u = pol.act(x0[:1], m)
    assert u.shape == (1,) and u[0] == ro.actions[0, 0]
    m = pol.step(m, ro.states[:1, 1])
    assert m.tolist() == pol.runtime.decode(ro.codes[:1, 1]).tolist()


@pytest.mark.parametrize("name, marking_obs", [("sac", "box"), ("ppo", "dict")])
def test_simulate_judges_an_sb3_model_and_check_reads_its_trace(models, tmp_path, name, marking_obs) -> None:
    sb3()
    runner = CliRunner()
    trace = tmp_path / "ro.csv"
    args = ["simulate", "--policy", str(models[name]), "--spec", str(models["spec"]), "--rollouts", "6"]
    r = runner.invoke(main, [*args, "--trace", str(trace)])
    assert r.exit_code == 0, r.output
    lines = r.output.splitlines()
    assert len(lines) == 8
    verdicts = []
    q0 = np.random.default_rng(0).uniform(-0.25, 0.25, 6)  # the seed's draws from the init box (qdot = 0)
    for i, line in enumerate(lines[:6]):
        m = LINE.match(line)
        assert m is not None, line
        assert (int(m[1]), m[2], m[3]) == (i, f"{q0[i]:.3f}", "0.000")
        _, _, ret, info = episode(models[name], models["spec"], np.array([q0[i], 0.0]), marking_obs)
        v = info["verdict"]  # the environment's verdict of the same episode
        if v["satisfied"]:
            assert m[4] == "satisfied"
        else:
            assert (float(m[5]), m[6]) == (round(v["violation_time"], 2), v["failing"])
        assert m[7] == f"{v['robustness']:+.3f}" and m[8] == f"{ret:.1f}"
        verdicts.append((v["satisfied"], v["robustness"]))
    satisfied = sum(s for s, _ in verdicts)
    where = "fresh starts drawn from the initial set, seed 0"
    assert lines[6] == f"{satisfied}/6 rollouts satisfy G[0,0.2] kappa ({where})"
    assert lines[7] == f"wrote 6 traces: {tmp_path / 'ro_000.csv'} .. {tmp_path / 'ro_005.csv'}"
    for i, (sat, rob) in enumerate(verdicts):
        c = runner.invoke(main, ["check", str(models["spec"]), str(tmp_path / f"ro_{i:03d}.csv")])
        assert c.exit_code == (0 if sat else 1), c.output
        out = c.output.splitlines()
        assert out[0].endswith("satisfied" if sat else "VIOLATED")
        assert out[2] == f"  robustness: {rob:.6g}"
    # no figure unless asked
    assert sorted(p.name for p in models[name].parent.iterdir() if p.suffix == ".png") == []
    fig = tmp_path / "sim.png"
    r = runner.invoke(main, [*args[:-1], "2", "--plot", str(fig)])
    assert r.exit_code == 0 and fig.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_simulate_refuses_bad_sb3_input_in_one_line(models, tmp_path) -> None:
    sb3()
    runner = CliRunner()
    spec = str(models["spec"])

    def fails(*args: str) -> str:
        r = runner.invoke(main, ["simulate", *args])
        assert r.exit_code == 2 and isinstance(r.exception, SystemExit), r.output
        assert "Traceback" not in r.output
        return r.output.strip()

    assert fails("--policy", str(models["sac"])) == (
        "--spec: error: a Stable-Baselines3 model does not record its spec: give the one it was trained on"
    )
    note = tmp_path / "model.txt"
    note.write_text("hi")
    assert fails("--policy", str(note), "--spec", spec) == (
        f"--policy {note}: error: a policy is a directory written by 'mitlc train' or a Stable-Baselines3 model .zip"
    )
    bad = tmp_path / "bad.zip"
    bad.write_text("not a zip")
    assert fails("--policy", str(bad), "--spec", spec) == (
        f"{bad}: error: not a Stable-Baselines3 model: a .zip that model.save() writes"
    )
    assert fails("--policy", str(models["sac"]), "--spec", "pendulum/p2_avoid") == (
        "mitlc:pendulum/p2_avoid.mitl: error: the model observes 6 numbers, and the plant's 2 with the marking make "
        "5 (the spec's net has 3 places): was it trained on another spec, or with other compile options?"
    )
    assert fails("--policy", str(models["sac"]), "--policy", str(models["ppo"]), "--spec", spec) == (
        "--policy: error: only HyRL policies (classical criteria) run composed; give one policy"
    )
    assert fails("--policy", str(models["sac"]), "--spec", spec, "--trace", str(tmp_path / "t.txt")) == (
        f"--trace {tmp_path / 't.txt'}: error: a trace is written as .csv or .npz"
    )


def test_simulate_without_sb3_says_what_to_install(tmp_path, monkeypatch) -> None:
    """Runs without Stable-Baselines3 too: there it is missing for real, here it is hidden."""
    monkeypatch.setitem(sys.modules, "stable_baselines3", None)  # import stable_baselines3 raises ImportError
    model = tmp_path / "model.zip"
    model.write_bytes(b"PK\x05\x06" + bytes(18))  # an empty zip: never opened
    r = CliRunner().invoke(main, ["simulate", "--policy", str(model), "--spec", "pendulum/p2_avoid"])
    assert r.exit_code == 2
    assert r.output.strip() == (
        f"{model}: error: loading a Stable-Baselines3 model needs Stable-Baselines3: pip install 'mitlc[sb3]'"
    )


def test_load_policy_points_an_sb3_model_to_load_sb3(tmp_path) -> None:
    from mitlc.errors import InputError
    from mitlc.learn.policy import load_policy

    model = tmp_path / "model.zip"
    model.write_bytes(b"PK\x05\x06" + bytes(18))
    with pytest.raises(InputError, match=r"mitlc.gym.load_sb3\(path, spec\) loads it as a Policy"):
        load_policy(model)
