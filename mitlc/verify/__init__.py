"""Policy, plant and spec to a sampled guarantee and counterexamples: verification.

In: a trained :class:`mitlc.learn.policy.Policy` (any object with its ``reset``, ``act`` and
``step``), the spec it is judged by (its plant, ``init`` box and ``formula`` or ``check``
line) and a :class:`~mitlc.verify.space.SearchSpace`: the ``init`` box, plant parameter
ranges (``--vary m=0.9:1.1``) and bounded input disturbances (``--disturb u=0.2``).
Out: :class:`~mitlc.verify.rollout.Judged` rollouts (states, inputs, the monitor's verdict
and robustness), the satisfied fraction with its exact one-sided Clopper-Pearson lower
bound (:func:`~mitlc.verify.stats.clopper_pearson_lower`), and a
:class:`~mitlc.verify.falsify.Search`: the least robust rollouts a budgeted optimiser
(CMA-ES, differential evolution or uniform sampling) found. Every batch of candidates
is rolled out at once along the plant's run axis.

:mod:`~mitlc.verify.space` maps points of the unit cube to starts, parameters and
disturbances; :mod:`~mitlc.verify.rollout` rolls them out and judges them;
:mod:`~mitlc.verify.stats` holds the bound; :mod:`~mitlc.verify.falsify` the search;
:mod:`~mitlc.verify.run` does both in order (:func:`~mitlc.verify.run.verify_policy`);
:mod:`~mitlc.verify.plots` draws a counterexample. ``mitlc verify`` (:mod:`mitlc.cli.verify`)
loads the policy, prints and writes the files.

May import: :mod:`mitlc.errors`, :mod:`mitlc.fileio`, :mod:`mitlc.limits`, :mod:`mitlc.plants`,
:mod:`mitlc.spec`, :mod:`mitlc.monitor`, :mod:`mitlc.cmaes`.
"""

from mitlc.verify.falsify import METHODS, Search, falsify
from mitlc.verify.rollout import Judged, judge, roll_out
from mitlc.verify.run import Outcome, verify_policy
from mitlc.verify.space import SearchSpace, parse_disturb, parse_vary
from mitlc.verify.stats import clopper_pearson_lower

__all__ = [
    "METHODS",
    "Judged",
    "Outcome",
    "Search",
    "SearchSpace",
    "clopper_pearson_lower",
    "falsify",
    "judge",
    "parse_disturb",
    "parse_vary",
    "roll_out",
    "verify_policy",
]
