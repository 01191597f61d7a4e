"""Deprecated: the counterfactual replay buffer moved to :mod:`mitlc.gym.crm`.

Importing this module warns once (a :class:`DeprecationWarning` naming the importer's line) and
gives the same objects as :mod:`mitlc.gym.crm`. It goes in the next release: import
``mitlc.gym.crm`` instead.
"""

import warnings

from mitlc.gym.crm import CounterfactualReplayBuffer, counterfactual_codes, find_net_env

__all__ = ["CounterfactualReplayBuffer", "counterfactual_codes", "find_net_env"]

warnings.warn(
    "mitlc.crm moved to mitlc.gym.crm; import it from there (mitlc.crm goes in the next release)",
    DeprecationWarning,
    stacklevel=2,
)
