"""
The Gymnasium environment
=========================

``teleopkit/FlexTeleop-v0`` is the teleoperator as a Gymnasium environment: every control period
(10 ms) an agent proposes the remote gains ``a = [K_r^1, K_r^2, B_r^1, B_r^2]``, the safety layer
projects them onto the certified gain set, and the simulator runs one period with the projected
gains. This tutorial drives it with a random policy and a constant one, and checks in the ``info``
of every step that each applied gain lies in the certified set.
"""

# %%
import os

import gymnasium as gym
import matplotlib.pyplot as plt
import numpy as np

import teleopkit  # noqa: F401  (registers teleopkit/FlexTeleop-v0)

BUDGET = os.environ.get("TELEOPKIT_DOCS_BUDGET", "full")
SMALL = BUDGET == "small"
EPISODE = 10.0 if SMALL else 40.0  # seconds (the paper's episodes last 40 s)

env = gym.make("teleopkit/FlexTeleop-v0", episode_length=EPISODE)
core = env.unwrapped
print(env.observation_space)
print(env.action_space)

# %%
# The certified set
# -----------------
# By default the environment certifies the box ``K_r in [1, 50]``, ``B_r in [1, 150]`` with the
# closed form for delays up to 1 s (:func:`teleopkit.rl.env.default_certificate`). The box itself is
# not certified; the certificate's polytope, the box cut by the closed-form half-plane of each
# joint, is, and the safety layer projects onto it.
certificate = core.certificate
print(certificate.method, certificate.gain_variation, certificate.certified)
print(core.safety_layer.polytope.joint_vertices(0).round(2))

# %%
# A random policy
# ---------------
# Uniform samples of the action space land outside the certified set often; the layer moves them
# to the nearest certified gain. ``info`` reports the raw and the applied action, the distance
# moved, the active constraints and whether a fallback was needed.
obs, info = env.reset(seed=0)
raw, applied, rewards = [], [], []
env.action_space.seed(0)
done = False
while not done:
    obs, reward, terminated, truncated, info = env.step(env.action_space.sample())
    raw.append(info["raw_action"])
    applied.append(info["applied_action"])
    rewards.append(reward)
    done = terminated or truncated
raw, applied = np.array(raw), np.array(applied)
inside = certificate.polytope.contains(applied)
print(f"{len(applied)} steps, {np.mean(~certificate.polytope.contains(raw)):.0%} of raw actions "
      f"outside the set, applied actions inside: {inside.all()}, unsafe count "
      f"{core.unsafe_actions}")
assert inside.all() and core.unsafe_actions == 0

# %%
# Note what the set covers: the closed-form certificate is for *frozen* gains
# (``certificate.gain_variation``), every constant gain in the set. A policy that changes the
# gains every step moves inside the set but is not covered by that certificate; gains switching
# arbitrarily fast need a ``switching`` certificate (the LMI method, see
# :doc:`/theory/certification`).

# %%
# Raw and applied gains of joint 1 in the ``(K_r, B_r)`` plane:
fig, ax = plt.subplots(figsize=(6, 4.5), layout="constrained")
polygon = certificate.polytope.joint_vertices(0)
ax.fill(polygon[:, 0], polygon[:, 1], color="0.88", label="certified set (joint 1)")
ax.plot(raw[:, 0], raw[:, 2], ".", ms=3, alpha=0.5, label="raw (random policy)")
ax.plot(applied[:, 0], applied[:, 2], ".", ms=3, label="applied")
ax.set_xlabel(r"$K_r$")
ax.set_ylabel(r"$B_r$")
ax.legend(fontsize="small", loc="upper left")

# %%
# A constant policy, and a broken one
# -----------------------------------
# A constant certified action passes unchanged (distance 0). A non-finite action (a diverged
# network, say) never reaches the plant: the layer applies a certified fallback and flags it.
obs, info = env.reset(seed=1)
constant = np.array([10.0, 10.0, 30.0, 30.0])
const_rewards, distances = [], []
for step in range(round(EPISODE / 0.01)):
    action = constant if step != 50 else np.full(4, np.nan)
    obs, reward, terminated, truncated, info = env.step(action)
    const_rewards.append(reward)
    distances.append(info["projection_distance"])
    if step == 50:
        print("NaN action -> applied", info["applied_action"], "fallback", info["fallback"])
    if terminated or truncated:
        break
print("largest distance on finite steps:", max(d for k, d in enumerate(distances) if k != 50))
print("unsafe actions so far:", core.unsafe_actions)

# %%
# Rewards ``-(alpha ||e_track||^2 + beta ||e_damp||^2 + gamma ||a||^2)`` of both episodes (the
# weights are :class:`teleopkit.rl.scoring.RewardWeights`): the opening transient dominates the
# first seconds, then the random gains keep costing while the constant ones settle.
t = 0.01 * np.arange(1, len(rewards) + 1)
fig, ax = plt.subplots(figsize=(7, 3), layout="constrained")
ax.plot(t, rewards, label="random policy")
ax.plot(t[:len(const_rewards)], const_rewards, label="constant K_r = 10, B_r = 30")
ax.set_yscale("symlog", linthresh=1.0)
ax.set_xlabel("time [s]")
ax.set_ylabel("reward per step")
ax.legend(fontsize="small")
env.close()
plt.show()
