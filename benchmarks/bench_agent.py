"""TD3 gradient updates per second (teleopkit vs Stable-Baselines3) and control-loop latency.

python benchmarks/bench_agent.py [--updates 300] [--calls 20000] [--threads 1]

Rows:

- **updates/s**: full TD3 gradient steps (both critics, and every second step the actor and the
  soft target updates) at batch 512 from a replay buffer of 100 000 random transitions, after 20
  warm-up steps; best of 3 repetitions. teleopkit's step also projects the target and actor
  actions onto the certified set and clips gradients (SB3's TD3 does neither). SB3 gets the same
  networks: its actor is ``net_arch`` 128-64 (tanh output) and each of its critics' Q-networks is
  replaced by teleopkit's two-path critic body (state 128-64, action 64, merged 60-36-1), so both
  sides do the same arithmetic per update.
- **latency**: one observation to one applied action, as in a 1 kHz haptic loop: numpy policy
  (:class:`teleopkit.rl.td3.GainPolicy`) + :meth:`SafetyLayer.project`, the torch actor +
  projection, and the projection alone by the compiled kernel and by the cvxpy + Clarabel
  reference (:meth:`SafetyLayer.project_qp`); p50 and p99 over ``--calls`` calls (the
  reference over 500).
- **projection by gain class**: the layer of each certificate class of the default box on a
  cycle of 64 random raw gains, the layer's run-time state kept between calls: ``frozen``
  (the closed-form polytope), ``scheduled:2`` (the coupled set of common shape, cone, box and
  the budget's floor, which it updates) and ``tank`` (the same with the tank's floor), and the
  tank's measurement of the state (remote energy and proven dissipation), once per period.
"""

from __future__ import annotations

import argparse
import os
import time
import warnings

import numpy as np
import torch
from torch import nn

from teleopkit.certification.certifier import default_certificate
from teleopkit.model.params import paper_setup
from teleopkit.rl.env import FlexTeleopVectorEnv
from teleopkit.rl.networks import Critic
from teleopkit.rl.replay import ReplayBuffer
from teleopkit.rl.td3 import TD3, TD3Config
from teleopkit.safety.factory import layer_for
from teleopkit.safety.layer import SafetyLayer
from teleopkit.sim import Simulator, paper_scenarios
from teleopkit.sim.energy import motor_speed_integral, remote_energy

OBS, ACT = 14, 4


def filled_buffer(layer, size: int = 100_000) -> ReplayBuffer:
    rng = np.random.default_rng(0)
    buffer = ReplayBuffer(size, OBS, ACT, seed=0)
    actions = layer.project_batch(rng.uniform(0, 150, (size, ACT))).action
    buffer.add(rng.normal(size=(size, OBS)), actions, -rng.random(size),
               rng.normal(size=(size, OBS)), np.zeros(size))
    return buffer


def rate(step, count: int, repeats: int = 3) -> float:
    for _ in range(20):
        step()
    best = 0.0
    for _ in range(repeats):
        start = time.perf_counter()
        for _ in range(count):
            step()
        best = max(best, count / (time.perf_counter() - start))
    return best


def teleopkit_rate(env, count: int) -> float:
    agent = TD3.for_env(env, TD3Config(), seed=0)
    buffer = filled_buffer(env.safety_layer)
    return rate(lambda: agent.update(buffer.sample(512)), count)


class _TwoPath(nn.Module):
    """teleopkit's critic body taking SB3's concatenated ``[obs, action]`` input."""

    def __init__(self, low: np.ndarray, high: np.ndarray) -> None:
        super().__init__()
        config = TD3Config()
        self.critic = Critic(OBS, low, high, torch.Generator().manual_seed(0),
                             config.hidden_state, config.hidden_action, config.hidden_merged)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.critic(x[:, :OBS], x[:, OBS:])[:, None]


def sb3_rate(count: int) -> float:
    import gymnasium
    from stable_baselines3 import TD3 as SB3TD3

    single = gymnasium.make("teleopkit/FlexTeleop-v0", episode_length=0.1)
    with warnings.catch_warnings():  # float64 bounds of the observation space cast to float32
        warnings.simplefilter("ignore", RuntimeWarning)
        single = gymnasium.wrappers.RescaleAction(single, -1.0, 1.0)
    model = SB3TD3("MlpPolicy", single, learning_rate=1e-4, batch_size=512, buffer_size=100_000,
                   policy_kwargs={"net_arch": {"pi": [128, 64], "qf": [128, 64]}}, seed=0,
                   device="cpu", verbose=0)
    policy = model.policy
    for critic in (policy.critic, policy.critic_target):
        for i in range(len(critic.q_networks)):
            body = _TwoPath(-np.ones(ACT), np.ones(ACT))
            critic.q_networks[i] = body
            critic.add_module(f"qf{i}", body)
    policy.critic_target.load_state_dict(policy.critic.state_dict())
    policy.critic.optimizer = torch.optim.Adam(policy.critic.parameters(), lr=1e-4)
    rng = np.random.default_rng(0)
    buffer = model.replay_buffer
    size = buffer.buffer_size
    buffer.observations[:size, 0] = rng.normal(size=(size, OBS))
    buffer.next_observations[:size, 0] = rng.normal(size=(size, OBS))
    buffer.actions[:size, 0] = rng.uniform(-1, 1, (size, ACT))
    buffer.rewards[:size, 0] = -rng.random(size)
    buffer.full = True
    model._logger = _NullLogger()
    return rate(lambda: model.train(gradient_steps=1, batch_size=512), count)


class _NullLogger:
    def record(self, *args, **kwargs) -> None:
        pass


def percentiles(call, count: int) -> tuple[float, float]:
    for _ in range(200):
        call()
    times = np.empty(count)
    for i in range(count):
        start = time.perf_counter_ns()
        call()
        times[i] = time.perf_counter_ns() - start
    return float(np.percentile(times, 50) / 1e3), float(np.percentile(times, 99) / 1e3)


def latency_rows(env, calls: int) -> list[tuple[str, float, float]]:
    agent = TD3.for_env(env, TD3Config(), seed=0)
    policy = agent.policy()
    layer = env.safety_layer
    obs_batch, _ = env.reset(seed=0)
    obs = obs_batch[0]
    obs_torch = torch.as_tensor(obs[None], dtype=torch.float32)
    raw = np.array([40.0, 10.0, 60.0, 30.0])  # outside the set: a real projection

    def torch_policy() -> np.ndarray:
        with torch.no_grad():
            action = agent.actor(obs_torch)[0].numpy().astype(np.float64)
        return layer.project(action).action

    return [
        ("numpy policy + projection", *percentiles(lambda: layer.project(policy(obs)), calls)),
        ("torch actor + projection", *percentiles(torch_policy, calls)),
        ("projection (compiled kernel)", *percentiles(lambda: layer.project(raw), calls)),
        ("projection (cvxpy + Clarabel)",
         *percentiles(lambda: layer.project_qp(raw), 500)),
    ]


def class_rows(calls: int) -> list[tuple[str, float, float]]:
    raws = np.random.default_rng(0).uniform([1, 1, 1, 1], [50, 50, 150, 150], (64, 4))
    params = paper_setup()
    state = Simulator(paper_scenarios(0, batch=1)).state

    def measure(layer: SafetyLayer) -> None:
        layer.observe(remote_energy(params, state), motor_speed_integral(state))

    rows = []
    for variation in ("frozen", "scheduled:2", "tank"):
        layer = layer_for(default_certificate(variation=variation))
        layer.reset()
        measure(layer)
        step = iter(range(10**9))
        rows.append((f"projection, {variation} class",
                     *percentiles(lambda layer=layer, step=step: layer.step(
                         raws[next(step) % len(raws)]), calls)))
    rows.append(("tank: measuring the state (once a period)",
                 *percentiles(lambda: measure(layer), calls // 10)))
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--updates", type=int, default=300)
    parser.add_argument("--calls", type=int, default=20_000)
    parser.add_argument("--threads", type=int, default=1)
    args = parser.parse_args()
    torch.set_num_threads(args.threads)
    env = FlexTeleopVectorEnv(1, episode_length=0.1)
    print(f"torch {torch.__version__}, {args.threads} thread(s), "
          f"load average {os.getloadavg()[0]:.2f}")
    print(f"{'TD3 gradient updates/s (batch 512)':<40} {'updates/s':>10}")
    print(f"{'teleopkit':<40} {teleopkit_rate(env, args.updates):>10.1f}")
    print(f"{'stable-baselines3':<40} {sb3_rate(args.updates):>10.1f}")
    print()
    print(f"{'latency, one sample':<40} {'p50 us':>10} {'p99 us':>10}")
    for name, p50, p99 in [*latency_rows(env, args.calls), *class_rows(args.calls)]:
        print(f"{name:<40} {p50:>10.1f} {p99:>10.1f}")
    print(f"load average {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
