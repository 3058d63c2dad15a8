"""Learning: the Gymnasium environments, TD3, the numpy policy, training, evaluation, baselines.

:mod:`~teleopkit.rl.env` holds the environments (registered as ``teleopkit/FlexTeleop-v0`` by
:mod:`~teleopkit.rl.registration`), which observe and reward the agent with
:mod:`~teleopkit.rl.scoring`; :mod:`~teleopkit.rl.td3` is the learner, built from
:mod:`~teleopkit.rl.networks`, :mod:`~teleopkit.rl.torch_projection` and
:mod:`~teleopkit.rl.replay`; :mod:`~teleopkit.rl.policy` is a trained actor in numpy;
:mod:`~teleopkit.rl.training` runs training with the settings and recipes of
:mod:`~teleopkit.rl.recipes`, :mod:`~teleopkit.rl.evaluation` compares
controllers on held-out scenarios and :mod:`~teleopkit.rl.baselines` finds the fixed and best
static gains. Only the learner, its networks and training need torch.
"""

from teleopkit._lazy import lazy_namespace

_EXPORTS = {
    "ENV_ID": "registration",
    "FlexTeleopConfig": "env",
    "FlexTeleopEnv": "env",
    "FlexTeleopVectorEnv": "env",
    "RewardWeights": "scoring",
    "GainPolicy": "policy",
    "TD3": "td3",
    "TD3Config": "td3",
    "RECIPES": "recipes",
    "TrainConfig": "recipes",
    "train": "training",
    "evaluate": "evaluation",
    "rollout": "evaluation",
    "best_static_gains": "baselines",
    "fixed_gains": "baselines",
}

__all__ = sorted(_EXPORTS)
__getattr__, __dir__ = lazy_namespace(__name__, globals(), _EXPORTS)
