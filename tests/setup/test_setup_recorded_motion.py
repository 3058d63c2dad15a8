"""A recorded operator motion must last the run, as a delay trace must: every run refuses one
that ends earlier (simulate, the environments, evaluation, campaigns) rather than hold its last
pose."""

from __future__ import annotations

import re
from dataclasses import replace
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

import teleopkit as tk
from teleopkit.rl.controllers import ConstantGains
from teleopkit.rl.env import FlexTeleopConfig, FlexTeleopVectorEnv
from teleopkit.rl.evaluation import closed_loop
from teleopkit.robustness.spec import CampaignSpec
from teleopkit.setup import Setup
from teleopkit.setup.reading import read_once
from teleopkit.sim.motions import RecordedMotion, check_motion_ends

ARM = {"local_arm": {"lengths": [0.38, 0.38], "masses": [0.5, 0.35]}}
ENDS_EARLY = "the recorded operator motion ends at 1 s, before the 2 s run does: record a " \
             "longer motion or shorten the run"


def _setup_with_motion(folder, end: float) -> Setup:
    t = np.linspace(0.0, end, 101)
    pd.DataFrame({"t": t, "q1": 0.3 * np.sin(t), "q2": 0.2 * np.sin(1.5 * t)}).to_csv(
        folder / "hand.csv", index=False)
    return Setup.from_data({"plant": ARM, "operator": {"motion": "csv:hand.csv"}}, folder)


@pytest.mark.parametrize(("end", "duration", "refused"), [
    (1.0, 2.0, True), (1.99, 2.0, True), (2.0, 2.0, False), (3.0, 2.0, False),
])
def test_a_motion_is_refused_exactly_when_it_ends_before_the_run(end, duration, refused):
    motion = RecordedMotion(np.array([0.0, end]), np.zeros((2, 2)))
    if refused:
        with pytest.raises(ValueError, match=f"ends at {end:g} s, before the 2 s run does"):
            check_motion_ends(motion, duration)
    else:
        check_motion_ends(motion, duration)


def test_simulate_refuses_a_motion_shorter_than_the_run_and_runs_a_long_enough_one(tmp_path):
    short = _setup_with_motion(tmp_path, 1.0)
    with pytest.raises(ValueError, match=re.escape(ENDS_EARLY)):
        tk.simulate((10.0, 30.0), duration=2.0, delay="constant:0.2", setup=short)
    table = tk.simulate((10.0, 30.0), duration=1.0, delay="constant:0.2", setup=short)
    assert len(table) == 101


def test_the_environments_and_evaluation_refuse_it(tmp_path):
    short = _setup_with_motion(tmp_path, 1.0)
    with pytest.raises(ValueError, match=re.escape(ENDS_EARLY)):
        FlexTeleopConfig(short, episode_length=2.0)  # training and evaluation, up front
    config = FlexTeleopConfig(episode_length=2.0)
    fixed = ConstantGains(np.array([10.0, 10.0, 30.0, 30.0]))
    with pytest.raises(ValueError, match=re.escape(ENDS_EARLY)):  # scenarios given as they are
        closed_loop(fixed, short.scenarios(0, 2), config)
    assert len(closed_loop(fixed, short.scenarios(0, 2), replace(config, episode_length=1.0))
               .reward) == 100
    FlexTeleopVectorEnv(2, FlexTeleopConfig(short, episode_length=1.0)).reset(seed=0)


def test_a_campaign_refuses_it_before_any_run(tmp_path):
    _setup_with_motion(tmp_path, 1.0)
    (tmp_path / "arm.yaml").write_text(
        "plant: {local_arm: {lengths: [0.38, 0.38], masses: [0.5, 0.35]}}\n"
        "network: {forward: {max: 0.3, profile: 'constant:0.2'}, "
        "backward: {max: 0.3, profile: 'constant:0.2'}}\n"
        "operator: {motion: csv:hand.csv}\n")
    spec = {"duration": 2.0, "setup": "arm.yaml", "factors": {"kr": [10]}}
    with pytest.raises(ValueError, match=re.escape(f"setup operator.motion: {ENDS_EARLY}")):
        CampaignSpec.from_dict(spec, tmp_path)
    assert CampaignSpec.from_dict({**spec, "duration": 1.0}, tmp_path).duration == 1.0


def test_a_setup_delay_trace_shorter_than_the_episodes_is_refused_by_the_environments(tmp_path):
    """The library refuses it up front, as the command line does (training, law search)."""
    t = np.linspace(0.0, 1.5, 16)
    pd.DataFrame({"time": t, "delay": 0.2 + 0.05 * np.sin(t)}).to_csv(tmp_path / "net.csv",
                                                                     index=False)
    channel = {"max": 0.3, "profile": "csv:net.csv"}
    setup = Setup.from_data({"plant": ARM, "network": {"forward": channel,
                                                       "backward": channel}}, tmp_path)
    with pytest.raises(ValueError, match=r"the delay trace ends at 1\.5 s, before the 2 s run"):
        FlexTeleopConfig(setup, episode_length=2.0)
    FlexTeleopConfig(setup, episode_length=1.5)


def test_a_recording_is_read_once_while_its_file_stays_as_it_is(tmp_path):
    path = tmp_path / "r.csv"
    path.write_text("a\n1\n")
    calls = []

    def reader(name: str) -> str:
        calls.append(name)
        return Path(name).read_text()

    assert read_once(reader, path) == read_once(reader, str(path)) == "a\n1\n"
    assert len(calls) == 1
    path.write_text("a\n1\n2\n")  # another size: read again
    assert read_once(reader, path) == "a\n1\n2\n" and len(calls) == 2
