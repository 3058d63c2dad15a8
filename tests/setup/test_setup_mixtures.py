"""Lists of motions and starts: each scenario draws one of them."""

from __future__ import annotations

import numpy as np
import pytest

from teleopkit.setup import Setup, SetupError, StartMix, paper_setup_path

ARM = {"local_arm": {"lengths": [0.38, 0.38], "masses": [0.5, 0.35]}}


def test_the_shipped_training_distribution_mixes_motions_starts_and_delays():
    setup = Setup.from_file(paper_setup_path().with_name("mixed_setup.yaml"))
    scenario = setup.scenarios(0, 64)
    assert isinstance(setup.start, StartMix) and setup.operator.motion.kind == "mix"
    amplitudes = scenario.motion.amplitudes
    assert amplitudes.shape[0] == 64
    assert np.any(np.all(amplitudes == 0, axis=(1, 2)))  # some operators stand still
    assert np.any(scenario.motion.decays == 0) and np.any(scenario.motion.decays > 0)
    starts = scenario.starts
    assert np.any(np.all(starts == 0, axis=(1, 2)))  # some at rest
    assert np.any(np.all(starts[:, 1] == starts[:, 2], axis=1) & np.any(starts[:, 0] != 0, axis=1))
    assert np.any(np.abs(starts) > 0.3) and np.all(np.abs(starts) <= 0.6)  # up to 0.6 rad
    delays = scenario.forward.sample(np.linspace(0, 10, 50))
    assert delays.shape == (50, 64) and 0.19 < delays.min() and delays.max() <= 1.0
    assert np.any(np.all(np.isclose(delays, 0.2), axis=0))  # constant 0.2 s
    assert np.any(np.all(np.isclose(delays, 0.6), axis=0))  # constant 0.6 s
    assert Setup.from_data(setup.to_data()) == setup


def test_a_mixed_batch_runs_each_scenario_as_its_own_part_would():
    """Each scenario of a mixed batch runs the motion and start it drew, as it would alone."""
    from dataclasses import replace

    from teleopkit.sim.motions import SineMotion
    from teleopkit.sim.simulator import Simulator

    constant = {"max": 0.5, "profile": "constant:0.4"}
    setup = Setup.from_data({"plant": ARM, "network": {"forward": constant, "backward": constant},
                             "operator": {"motion": [
        "paper", {"smooth": {"amplitude": [0.2, 1.0], "frequency": [0.1, 1.0]}}, "still"]},
        "start": ["rest", {"local": {"min": [-0.3, -0.3], "max": [0.3, 0.3]}}]})
    batch = setup.scenarios(5, 4)
    gains = np.array([5.0, 5.0, 20.0, 20.0])
    together = Simulator(batch).run(0.5, gains).state
    for b in range(4):
        alone = replace(batch, reference_gains=batch.reference_gains[b:b + 1],
                        motion=SineMotion(*(getattr(batch.motion, k)[b:b + 1] for k in (
                            "amplitudes", "frequencies", "phases", "decays"))),
                        start=batch.starts[b:b + 1])
        np.testing.assert_allclose(together[:, b], Simulator(alone).run(0.5, gains).state[:, 0],
                                   rtol=0, atol=1e-12)


def test_a_list_of_motions_refuses_a_recorded_one(tmp_path):
    (tmp_path / "hand.csv").write_text("t,q1,q2\n0,0,0\n50,1,1\n")
    with pytest.raises(SetupError, match="a list of motions takes paper, still, sines and smooth"):
        Setup.from_data({"plant": ARM, "operator": {"motion": ["paper", "csv:hand.csv"]}},
                        tmp_path)
