"""Use a compiled reward system with any Gymnasium environment: the edge to other learners.

In: a :class:`~mitlc.petri.RewardSystem` (or a :class:`~mitlc.spec.Spec`, or the path of a
``.mitl`` file) and a Gymnasium environment. Out: :class:`MitlRewardWrapper`, the environment
paying the compiled reward. May import: :mod:`mitlc.errors`, :mod:`mitlc.fileio`,
:mod:`mitlc.limits`, :mod:`mitlc.plants`, :mod:`mitlc.spec`, :mod:`mitlc.petri`, :mod:`mitlc.monitor`,
:mod:`mitlc.runtime`, :mod:`mitlc.learn`.

:class:`MitlRewardWrapper` (:mod:`~mitlc.gym.wrapper`) steps the reward net beside any
Gymnasium environment and pays its reward. :class:`MitlPlantEnv` (:mod:`~mitlc.gym.envs`,
registered as ``mitlc/Pendulum-v0``, ``mitlc/MassDamper-v0`` when this package is imported) is
one of mitlc's plants as an environment paying the same reward, with the same marking, clocks
and ``info``. Both are a :class:`MitlNetEnv` (:mod:`~mitlc.gym.netenv`, the net stepped beside
an episode): the interface :class:`mitlc.gym.crm.CounterfactualReplayBuffer` and
:class:`Sb3Policy` (:mod:`~mitlc.gym.sb3`: a Stable-Baselines3 model trained on them as a
:class:`mitlc.learn.policy.Policy`, for ``mitlc simulate --policy model.zip``) read.
:class:`SacRuns` (:mod:`~mitlc.gym.sac`, ``mitlc train --learner sac``) trains Stable-Baselines3's SAC
run by run on :class:`MitlPlantEnv`, and :func:`load_policy` loads such a folder as well as SACPN's and HyRL's.
:mod:`~mitlc.gym.observation` reads the spec's state off an observation (``observe``,
:func:`pendulum_v1_state`) and lays out the marking and clocks beside it.

Gymnasium is an optional dependency: ``pip install 'mitlc[gym]'``. Importing this package
imports neither Stable-Baselines3 nor PyTorch: :func:`load_sb3` does, and so does
:mod:`mitlc.gym.crm` (``pip install 'mitlc[sb3]'``), which is imported only by name.
"""

try:
    import gymnasium  # noqa: F401 - every module here needs it
except ImportError as exc:  # pragma: no cover - exercised in a subprocess by tests/test_gym.py
    raise ImportError("mitlc.gym needs Gymnasium, an optional dependency: pip install 'mitlc[gym]'") from exc

from mitlc.gym.envs import ENV_IDS, MitlPlantEnv
from mitlc.gym.netenv import VERDICT, MarkingCodes, MitlNetEnv
from mitlc.gym.observation import MARKING_OBS, Observe, pendulum_v1_state, plant_observation
from mitlc.gym.sac import SacRuns, SacSettings, load_policy
from mitlc.gym.sb3 import SB3_EXTRA, Sb3Policy, load_sb3, sb3_algorithm
from mitlc.gym.wrapper import MitlRewardWrapper

__all__ = [
    "MitlRewardWrapper",
    "MitlPlantEnv",
    "MitlNetEnv",
    "MarkingCodes",
    "ENV_IDS",
    "pendulum_v1_state",
    "plant_observation",
    "Sb3Policy",
    "load_sb3",
    "SacRuns",
    "SacSettings",
    "load_policy",
    "sb3_algorithm",
    "SB3_EXTRA",
    "Observe",
    "MARKING_OBS",
    "VERDICT",
]
