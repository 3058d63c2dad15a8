"""Robustness: campaigns over thousands of scenarios, and falsification of certified sets.

A campaign (:mod:`~teleopkit.robustness.campaign`) crosses or samples the factors of
:mod:`~teleopkit.robustness.factors` as a spec (:mod:`~teleopkit.robustness.spec`), simulates
chunks of scenarios on Dask (:mod:`~teleopkit.robustness.chunks`) and keeps them as files
(:mod:`~teleopkit.robustness.store`). Falsification looks for the worst delays and gains inside a
certified set, by sampling (:mod:`~teleopkit.robustness.falsification`) or by search
(:mod:`~teleopkit.robustness.search`): evidence, never proof.
"""

from teleopkit._lazy import lazy_namespace

_EXPORTS = {
    "CampaignInterrupted": "campaign",
    "local_cluster": "campaign",
    "run_campaign": "campaign",
    "CampaignSpec": "spec",
    "FACTORS": "factors",
    "Factor": "factors",
    "falsify": "falsification",
    "sample_polytope": "falsification",
    "SearchResult": "search",
    "SearchSpace": "adversary",
}
# the search itself is teleopkit.robustness.search.search: a package attribute of that name would
# hide the module

__all__ = sorted(_EXPORTS)
__getattr__, __dir__ = lazy_namespace(__name__, globals(), _EXPORTS)
