"""
Use the Gymnasium environment with another RL library
=====================================================

``teleopkit/FlexTeleop-v0`` is a plain Gymnasium environment, so any library that speaks
Gymnasium can train on it; the safety layer sits inside the environment, so whatever the library's
agent outputs, only certified gains reach the simulator. This tutorial trains the TD3 of
`Stable-Baselines3 <https://stable-baselines3.readthedocs.io>`_ (SB3) for a few steps, evaluates
it with SB3's tools, and checks in the ``info`` of every step that the applied gains lie in the
certified set. SB3 is an optional extra of teleopkit::

    pip install -c constraints.txt -e ".[sb3]"

Without it the tutorial runs the same loop with Gymnasium's own wrappers and a hand-written
policy in place of the SB3 agent.
"""

# %%
# Budget
# ------
# ``TELEOPKIT_DOCS_BUDGET=small`` (the documentation build) trains for 400 steps on 1 s episodes:
# enough to show the plumbing, far too little to learn anything. ``full`` trains for 20 000 steps
# on 10 s episodes (a few minutes), still a short run by the standards of the problem (the shipped
# pretrained policy of teleopkit's own trainer saw 1.6 million transitions).
import importlib.util
import os
import time

import gymnasium as gym
import matplotlib.pyplot as plt
import numpy as np
import torch
from gymnasium.wrappers import RecordEpisodeStatistics, RescaleAction
from gymnasium.wrappers import vector as vector_wrappers

import teleopkit  # noqa: F401  (registers teleopkit/FlexTeleop-v0)
from teleopkit.rl.baselines import fixed_gains
from teleopkit.rl.env import ENV_ID

torch.set_num_threads(1)  # small networks; one core is enough

BUDGET = os.environ.get("TELEOPKIT_DOCS_BUDGET", "full")
SMALL = BUDGET == "small"
EPISODE = 1.0 if SMALL else 10.0  # seconds (the paper's episodes last 40 s)
STEPS = 400 if SMALL else 20_000  # environment steps of training (10 ms each)
EVAL_EPISODES = 2 if SMALL else 5
NUM_ENVS = 8  # scenarios of the batched environment at the end

HAVE_SB3 = importlib.util.find_spec("stable_baselines3") is not None
if not HAVE_SB3:
    print('stable-baselines3 is not installed; install it with\n'
          '    pip install -c constraints.txt -e ".[sb3]"\n'
          "Below: the same loop with Gymnasium wrappers and a fixed policy instead of SB3's TD3.")

# %%
# The environment
# ---------------
# The action space is the certificate's gain box ``K_r in [1, 50]``, ``B_r in [1, 150]``; most RL
# libraries, SB3 included, expect actions in ``[-1, 1]``. Gymnasium's
# ``gymnasium.wrappers.RescaleAction`` maps ``[-1, 1]`` affinely onto the box. The
# environment still projects the rescaled gains onto the certified set, and its ``info`` reports
# raw and applied gains in gain units.
def make_env():
    """``teleopkit/FlexTeleop-v0`` with actions in ``[-1, 1]``."""
    env = gym.make(ENV_ID, episode_length=EPISODE)
    return RescaleAction(env, min_action=-1.0, max_action=1.0)


probe = make_env()
print(probe.action_space)
print(probe.observation_space)
box = probe.unwrapped.action_space  # the gain box, in gain units
probe.close()

# %%
# Training
# --------
# With SB3, the environment is wrapped in SB3's ``Monitor``, which records the return and length
# of every episode, and SB3's ``TD3`` trains on it with Gaussian exploration noise (in the
# ``[-1, 1]`` units of the actions; exploration noise too is projected before it reaches the
# plant). The observations span several orders of magnitude; a real run would standardise them
# (SB3's ``VecNormalize``), as teleopkit's own TD3 does (:doc:`/theory/agent`).
#
# Without SB3 the same loop runs with Gymnasium's ``RecordEpisodeStatistics`` in place of
# ``Monitor`` and a fixed policy with exploration noise in place of the agent: the paper's
# fixed gains ``K_r = 10, B_r = 30``, expressed in ``[-1, 1]`` units.
rng = np.random.default_rng(0)
if HAVE_SB3:
    from stable_baselines3 import TD3
    from stable_baselines3.common.evaluation import evaluate_policy
    from stable_baselines3.common.monitor import Monitor
    from stable_baselines3.common.noise import NormalActionNoise

    env = Monitor(make_env())
    model = TD3("MlpPolicy", env, learning_rate=1e-3, learning_starts=100 if SMALL else 1_000,
                batch_size=64 if SMALL else 256,
                action_noise=NormalActionNoise(np.zeros(4), np.full(4, 0.2)),
                policy_kwargs={"net_arch": [128, 64]}, seed=0, verbose=0)
    start = time.perf_counter()
    model.learn(total_timesteps=STEPS)
    train_returns = env.get_episode_rewards()

    def policy(obs):
        """The trained SB3 actor, deterministic (one observation or a batch)."""
        return model.predict(obs, deterministic=True)[0]
else:
    env = RecordEpisodeStatistics(make_env())
    centre = 2.0 * (fixed_gains() - box.low) / (box.high - box.low) - 1.0

    def policy(obs):
        """The paper's fixed gains in ``[-1, 1]`` units (one observation or a batch)."""
        return np.broadcast_to(centre, (*np.shape(obs)[:-1], 4)).copy()

    start = time.perf_counter()
    train_returns = []
    obs, _ = env.reset(seed=0)
    for _ in range(STEPS):
        action = np.clip(policy(obs) + 0.2 * rng.standard_normal(4), -1.0, 1.0)
        obs, reward, terminated, truncated, info = env.step(action)
        if terminated or truncated:
            train_returns.append(float(info["episode"]["r"]))
            obs, _ = env.reset()
print(f"{STEPS} steps in {time.perf_counter() - start:.1f} s; episode returns:",
      np.round(train_returns, 1))

# %%
# Evaluation
# ----------
# SB3's ``evaluate_policy`` runs the deterministic policy for a few episodes and reads the returns
# from the ``Monitor``; without SB3 the same episodes run by hand. Each episode draws a new
# scenario (operator reference and delay scales).
if HAVE_SB3:
    returns, lengths = evaluate_policy(model, env, n_eval_episodes=EVAL_EPISODES,
                                       deterministic=True, return_episode_rewards=True)
else:
    returns, lengths = [], []
    for _ in range(EVAL_EPISODES):
        obs, _ = env.reset()
        done = False
        while not done:
            obs, reward, terminated, truncated, info = env.step(policy(obs))
            done = terminated or truncated
        returns.append(float(info["episode"]["r"]))
        lengths.append(int(info["episode"]["l"]))
print("evaluation returns:", np.round(returns, 1), "lengths:", lengths)

# %%
# Every applied action is certified
# ---------------------------------
# One more episode by hand: the policy's action in ``[-1, 1]``, the raw gains it stands for
# (``info["raw_action"]``) and the gains the safety layer applied (``info["applied_action"]``).
# Every applied action lies in the certificate's polytope, and the environment's counter of
# applied actions outside it, ``env.unwrapped.unsafe_actions``, is zero for everything that ran in
# it: training, evaluation and this episode.
core = env.unwrapped
obs, _ = env.reset(seed=1)
raw, applied, distances = [], [], []
done = False
while not done:
    obs, reward, terminated, truncated, info = env.step(policy(obs))
    raw.append(info["raw_action"])
    applied.append(info["applied_action"])
    distances.append(info["projection_distance"])
    done = terminated or truncated
raw, applied = np.array(raw), np.array(applied)
inside = core.certificate.polytope.contains(applied)
print(f"{len(applied)} steps: applied actions inside the certified set: {inside.all()}; "
      f"projected steps: {np.count_nonzero(np.array(distances) > 0)}; "
      f"unsafe actions: {core.unsafe_actions}")
assert inside.all() and core.unsafe_actions == 0

# %%
# As in :doc:`/auto_examples/plot_gymnasium`: the certificate behind the set (the closed form of
# :func:`teleopkit.rl.env.default_certificate`) covers *frozen* gains, every constant gain in the
# set; a policy that changes the gains every 10 ms moves inside the set but needs a ``switching``
# or ``rate:R`` certificate (:doc:`/theory/certification`) to be covered as it varies.
print("gain variation covered:", core.certificate.gain_variation)

fig, axes = plt.subplots(1, 2, figsize=(9, 3.5), layout="constrained")
polygon = core.certificate.polytope.joint_vertices(0)
axes[0].fill(polygon[:, 0], polygon[:, 1], color="0.88", label="certified set (joint 1)")
axes[0].plot(raw[:, 0], raw[:, 2], "x", ms=4, label="raw")
axes[0].plot(applied[:, 0], applied[:, 2], ".", ms=3, label="applied")
axes[0].set_xlabel(r"$K_r$")
axes[0].set_ylabel(r"$B_r$")
axes[0].legend(fontsize="small", loc="upper left")
t = 0.01 * np.arange(1, len(applied) + 1)
axes[1].plot(t, applied[:, 0], label=r"$K_{r,1}$")
axes[1].plot(t, applied[:, 2], label=r"$B_{r,1}$")
axes[1].set_xlabel("time [s]")
axes[1].set_ylabel("applied gain")
axes[1].legend(fontsize="small")

# %%
# The natively batched environment
# --------------------------------
# teleopkit also registers a vector entry point: :class:`teleopkit.rl.env.FlexTeleopVectorEnv`
# simulates ``num_envs`` scenarios in one compiled simulator call with one batched projection
# (what teleopkit's own trainer, :func:`teleopkit.rl.training.train`, collects experience with).
# ``gymnasium.make_vec`` builds it with ``vectorization_mode="vector_entry_point"``, and
# Gymnasium's vector wrappers apply to it. SB3 drives its own ``VecEnv`` API rather than
# Gymnasium's vector environments (its ``DummyVecEnv`` steps copies of the single environment
# one after the other), but a trained SB3 policy acts on a batch of observations directly.
vec = gym.make_vec(ENV_ID, num_envs=NUM_ENVS, vectorization_mode="vector_entry_point",
                   episode_length=EPISODE)
vec = vector_wrappers.RecordEpisodeStatistics(vector_wrappers.RescaleAction(vec, -1.0, 1.0))
print(vec.unwrapped)
obs, _ = vec.reset(seed=2)
start = time.perf_counter()
done = False
while not done:
    obs, reward, terminated, truncated, info = vec.step(policy(obs))
    done = bool(np.any(terminated | truncated))
elapsed = time.perf_counter() - start
print(f"{NUM_ENVS} episodes at once in {elapsed:.2f} s; returns:",
      np.round(info["episode"]["r"], 1))
print("unsafe actions:", vec.unwrapped.unsafe_actions)
assert vec.unwrapped.unsafe_actions == 0
vec.close()
env.close()
plt.show()
