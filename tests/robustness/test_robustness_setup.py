"""Campaigns vary a setup: its plant, operator motions, starts and network."""

from __future__ import annotations

import numpy as np
import pytest

import teleopkit as tk
from teleopkit.cli import main
from teleopkit.robustness.campaign import run_campaign
from teleopkit.robustness.spec import CampaignSpec

SETUP = """\
plant:
  local_arm:  {lengths: [0.3, 0.25], masses: [0.8, 0.5]}
  remote_arm: {lengths: [0.45, 0.35], masses: [1.2, 0.6], com: [0.2, 0.15], inertia: [0.01, 0.005]}
  joints:     {stiffness: [60, 80], rotor_inertia: [0.2, 0.2]}
  local_gains: {stiffness: [20, 20], damping: [8, 8]}
network:
  forward:  {min: 0.05, max: 0.6, profile: "sine:0.3:0.2:0.5"}
  backward: {min: 0.05, max: 0.6, profile: "switching:0.05:0.6:50ms"}
operator: {motion: {smooth: {amplitude: [0.3, 0.8], frequency: [0.1, 0.8]}}}
start: {local: {min: [-0.3, -0.3], max: [0.3, 0.3]}}
"""


@pytest.fixture
def setup_file(tmp_path):
    path = tmp_path / "arm.yaml"
    path.write_text(SETUP)
    return path


def test_a_campaign_row_reproduces_simulate_on_the_setup(setup_file, tmp_path):
    spec = tmp_path / "spec.yaml"
    spec.write_text("duration: 1.0\nsetup: arm.yaml\nfactors: {kr: [5, 10], seed: [3, 4]}\n")
    loaded = CampaignSpec.from_file(spec)
    table = run_campaign(loaded, tmp_path / "r.parquet", client="synchronous", chunk=3)
    setup = tk.Setup.from_file(setup_file)
    assert (table["delay"] == "setup").all() and (table["kl"] == 20).all()
    assert table["joint_stiffness"].isna().all()  # 60 and 80: not one number
    assert (table["delay_bound"] <= 0.6).all()
    for row in table.itertuples():
        run = tk.simulate((row.kr, row.br), duration=1.0, seed=row.seed, setup=setup)
        norm = np.linalg.norm(run[["e_track_1", "e_track_2"]].to_numpy(), axis=1)
        rms = np.sqrt(np.trapezoid(norm**2, run["t"]) / 1.0)
        assert row.rms_track == pytest.approx(rms, rel=1e-12)


def test_the_setup_option_overrides_the_spec_and_changes_the_rows(setup_file, tmp_path):
    spec = tmp_path / "spec.yaml"
    spec.write_text("duration: 1.0\nfactors: {kr: [10], joint_stiffness: [100]}\n")
    paper = tmp_path / "paper.csv"
    ours = tmp_path / "ours.csv"
    assert main(["campaign", str(spec), "--out", str(paper), "--workers", "1"]) == 0
    assert main(["campaign", str(spec), "--out", str(ours), "--workers", "1", "--setup",
                 str(setup_file)]) == 0
    import pandas as pd

    a, b = pd.read_csv(paper), pd.read_csv(ours)
    assert a.loc[0, "delay"] == "paper" and b.loc[0, "delay"] == "setup"
    assert b.loc[0, "joint_stiffness"] == 100 and b.loc[0, "kl"] == 20
    assert a.loc[0, "rms_track"] != b.loc[0, "rms_track"]
