"""Bad inputs, table-driven: every one gives its exact, one-line error (exit 2 on the CLI).

CLI cases run ``teleopkit.cli.main([...])`` in-process and compare the captured standard error
with ``teleopkit: error: MESSAGE``; API cases compare ``str(ValueError)`` with MESSAGE. ``{tmp}``
in arguments and messages stands for the test's temporary directory.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from teleopkit.certification import GainCertificate, certify_gains
from teleopkit.certification.gain_sets import GainBox
from teleopkit.cli import main
from teleopkit.delays import PiecewiseDelay, TraceDelay, parse_delay
from teleopkit.model.params import paper_setup
from teleopkit.robustness.adversary import SearchSpace
from teleopkit.robustness.campaign import run_campaign
from teleopkit.robustness.search import search
from teleopkit.robustness.spec import CampaignSpec
from teleopkit.sim.scenarios import Scenario, paper_scenarios
from teleopkit.sim.simulator import Simulator

TINY = {"duration": 0.2, "factors": {"kr": [10, 20, 30]}}
KNOWN = ("joint_stiffness, rotor_inertia, remote_mass_scale, local_mass_scale, kl, bl, delay, "
         "delay_scale, reference_gain, kr, br, seed, controller")
SIM = ["simulate", "--kr", "10", "--br", "30", "--out", "{tmp}/x.csv"]
CERT = ["certify", "--kr", "1:5", "--br", "30:60"]


def write(name: str, text: str) -> Callable[[Path], None]:
    """Setup: write a file in the temporary directory."""
    return lambda tmp: (tmp / name).write_text(text)


def interrupted(tmp: Path) -> None:
    """Setup: a campaign stopped after some chunks (its output table was never written)."""
    (tmp / "ok.yaml").write_text(json.dumps(TINY))
    run_campaign(TINY, tmp / "o.csv", client="synchronous", chunk=1)
    (tmp / "o.csv").unlink()
    (tmp / "o.csv.chunks" / "chunk-000001.parquet").unlink()


def other_campaign(tmp: Path) -> None:
    """Setup: chunks of a different campaign in the output's chunk directory."""
    (tmp / "ok.yaml").write_text(json.dumps(TINY))
    run_campaign({**TINY, "duration": 0.1}, tmp / "o.csv", client="synchronous", chunk=1)


def no_setup(tmp: Path) -> None:
    """Setup: nothing."""


OK_SPEC = write("ok.yaml", json.dumps(TINY))

CLI_CASES = [
    # simulate: numbers, shapes, delay specs, files
    (["simulate", "--kr", "-1", "--br", "30", "--out", "{tmp}/x.csv"], no_setup,
     "Invalid value: --kr must be finite and non-negative, got '-1'"),
    (["simulate", "--kr", "abc", "--br", "30", "--out", "{tmp}/x.csv"], no_setup,
     "Invalid value: --kr must be a number or a comma list, got 'abc'"),
    (["simulate", "--kr", "10", "--br", "1,2,3", "--out", "{tmp}/x.csv"], no_setup,
     "Invalid value: --br needs 1 or 2 values, got 3"),
    ([*SIM, "--duration", "0"], no_setup, "duration must be positive, got 0.0"),
    ([*SIM, "--dt", "0"], no_setup, "integration step must be positive, got 0.0"),
    ([*SIM, "--delay", "warp:3"], no_setup,
     "unknown delay spec 'warp:3'; use paper, constant:T, sine:MEAN:AMP:FREQ, "
     "switching:LOW:HIGH:DWELL or csv:PATH"),
    ([*SIM, "--delay", "constant:-0.5"], no_setup,
     "constant delay must be non-negative, got [-0.5]"),
    ([*SIM, "--delay", "csv:{tmp}/trace.csv"], write("trace.csv", "t,delay\n0,0.1\n0,0.2\n"),
     "delay trace times must be strictly increasing"),
    (["simulate", "--kr", "10", "--br", "30"], no_setup, "Missing option '--out'."),
    # certify: ranges and bounds
    (["certify", "--kr", "5:1", "--br", "30:60"], no_setup, "--kr range is inverted (5.0 > 1.0)"),
    (["certify", "--kr", "a:b", "--br", "30:60"], no_setup,
     "--kr must be MIN:MAX with numbers, got 'a:b'"),
    ([*CERT, "--tl-max", "0"], no_setup,
     "delay bound T_l* must be positive and finite, got 0.0"),
    ([*CERT, "--gain-variation", "rate:x"], no_setup,
     "gain variation rate: 'x' is not a number"),
    ([*CERT, "--gain-variation", "switching"], no_setup,
     "the closed form (nuno) covers frozen, scheduled:L and tank gains, not switching gains; "
     "certify those with the LMIs (method lmi)"),
    # campaign: spec files, outputs, options, interrupted campaigns
    (["campaign", "{tmp}/missing.yaml", "--out", "{tmp}/o.csv"], no_setup,
     "cannot read campaign spec {tmp}/missing.yaml: No such file or directory"),
    (["campaign", "{tmp}/u.yaml", "--out", "{tmp}/o.csv"],
     write("u.yaml", "factors:\n  stifness: [1, 2]\n"),
     f"{{tmp}}/u.yaml: unknown factor 'stifness'; known: {KNOWN}"),
    (["campaign", "{tmp}/s.yaml", "--out", "{tmp}/o.csv"], write("s.yaml", "factors: [kr: 1\n"),
     "cannot parse campaign spec {tmp}/s.yaml: expected ',' or ']', but got '<stream end>' "
     "(line 2, column 1)"),
    (["campaign", "{tmp}/b.json", "--out", "{tmp}/o.csv"], write("b.json", '{"factors": '),
     "cannot parse campaign spec {tmp}/b.json: Expecting value: line 1 column 13 (char 12)"),
    (["campaign", "{tmp}/s.txt", "--out", "{tmp}/o.csv"], write("s.txt", "kr: 1"),
     "campaign spec {tmp}/s.txt must be .yaml, .yml, .json or .toml"),
    (["campaign", "{tmp}/r.yaml", "--out", "{tmp}/o.csv"], write("r.yaml", "mode: random\n"),
     "{tmp}/r.yaml: campaign samples must be an integer >= 1, got 0"),
    (["campaign", "{tmp}/ok.yaml", "--out", "{tmp}/o.txt"], OK_SPEC,
     "campaign output {tmp}/o.txt must end in .parquet or .csv"),
    (["campaign", "{tmp}/ok.yaml", "--out", "{tmp}/o.csv", "--workers", "0"], OK_SPEC,
     "Invalid value for '--workers': 0 is not in the range x>=1."),
    (["campaign", "{tmp}/ok.yaml", "--out", "{tmp}/o.csv", "--workers", "2", "--scheduler",
      "tcp://127.0.0.1:1"], OK_SPEC,
     "--workers sizes the local cluster; it cannot be combined with --scheduler"),
    (["campaign", "{tmp}/ok.yaml", "--out", "{tmp}/o.csv"], interrupted,
     "{tmp}/o.csv.chunks holds chunks of an earlier run: pass --resume to continue it, or "
     "delete it"),
    (["campaign", "{tmp}/ok.yaml", "--out", "{tmp}/o.csv", "--resume", "--scheduler",
      "synchronous"], other_campaign,
     "{tmp}/o.csv.chunks holds chunks of another campaign or chunk size; use another output "
     "or delete it"),
    # falsify and train
    (["falsify", "--kr", "1:50", "--br", "1:150", "--budget", "1"], no_setup,
     "Invalid value for '--budget': 1 is not in the range x>=2."),
    (["falsify", "--kr", "1:50", "--br", "1:150", "--tl-max", "-1"], no_setup,
     "delay bound T_l* must be positive and finite, got -1.0"),
    (["train", "--steps", "0"], no_setup,
     "Invalid value for '--steps': 0 is not in the range x>=1."),
]


@pytest.mark.parametrize(("args", "setup", "message"), CLI_CASES,
                         ids=[" ".join(case[0][:3]) for case in CLI_CASES])
def test_cli_bad_input_exits_2_with_the_exact_one_line_error(tmp_path, capsys, args, setup,
                                                              message):
    setup(tmp_path)
    capsys.readouterr()
    code = main([a.format(tmp=tmp_path) for a in args])
    err = capsys.readouterr().err
    assert code == 2
    assert err == f"teleopkit: error: {message.format(tmp=tmp_path)}\n"


def certificate_data() -> dict:
    box = GainBox.uniform((1.0, 5.0), (30.0, 60.0))
    return certify_gains(paper_setup(), box, 1.0, 1.0).to_dict()


def with_changes(**changes: object) -> str:
    data = certificate_data()
    for key, value in changes.items():
        section, _, field = key.partition("__")
        if field:
            data[section][field] = value
        else:
            data[section] = value
    return json.dumps(data)


def nuno_space(**options: object) -> SearchSpace:
    box = GainBox.uniform((1.0, 50.0), (1.0, 150.0))
    return SearchSpace(paper_setup(), certify_gains(paper_setup(), box), **options)


API_CASES = [
    # corrupted certificates
    (lambda: GainCertificate.from_json("not json"),
     "malformed gain certificate: Expecting value: line 1 column 1 (char 0)"),
    (lambda: GainCertificate.from_json("{}"), "malformed gain certificate: 'box'"),
    (lambda: GainCertificate.from_json(with_changes(polytope__h=[1.0, 2.0])),
     "malformed gain certificate: polytope has 10 normals, 2 offsets and 10 labels"),
    (lambda: GainCertificate.from_json(with_changes(box__kr=[[5.0, 1.0], [1.0, 5.0]])),
     "malformed gain certificate: K_r range is inverted (5.0 > 1.0)"),
    (lambda: GainCertificate.from_json(with_changes(polytope__G="oops")),
     "malformed gain certificate: could not convert string to float: 'oops'"),
    # delays
    (lambda: parse_delay("sine:1:2"),
     "unknown delay spec 'sine:1:2'; use paper, constant:T, sine:MEAN:AMP:FREQ, "
     "switching:LOW:HIGH:DWELL or csv:PATH"),
    (lambda: TraceDelay(np.array([0.0, 1.0]), np.array([0.1])),
     "delay trace needs two equal-length columns with at least 2 rows"),
    (lambda: PiecewiseDelay(np.zeros((1, 2)), np.zeros((1, 3))),
     "piecewise delay needs times and values of one shape (B, K), got (1, 2) and (1, 3)"),
    # shapes and numbers of the simulator
    (lambda: Simulator(paper_scenarios(0, batch=2)).advance(np.ones(3)),
     "remote gains need 4 values [K_r..., B_r...] on the last axis, got shape (3,)"),
    (lambda: Scenario(reference_gains=np.ones((1, 3))),
     "reference gains need shape (batch, 2), got (1, 3)"),
    (lambda: GainBox.uniform((1.0, 5.0), (30.0, -60.0)),
     "B_r range is inverted (30.0 > -60.0)"),
    # campaign specs
    (lambda: CampaignSpec.from_dict({"factors": {"kr": [-1]}}),
     "factor 'kr': values must be finite and >= 0, got -1"),
    (lambda: CampaignSpec.from_dict({"factors": {"kr": {"uniform": [1, 2]}}}),
     "factor 'kr': uniform draws need mode: random; a grid takes a list, linspace or range"),
    (lambda: CampaignSpec.from_dict({"factors": {"delay": []}}), "factor 'delay' has no values"),
    (lambda: CampaignSpec.from_dict({"duration": 0}),
     "campaign duration must be positive and finite, got 0"),
    (lambda: CampaignSpec.from_dict({"dt": 0.001, "control_period": 0.0125}),
     "campaign control period 0.0125 s must be a positive multiple of the integration step "
     "0.001 s"),
    (lambda: CampaignSpec.from_dict({"factors": {"bl": {"linspace": [1, 2]}}}),
     "factor 'bl': linspace needs a list of 3 numbers"),
    (lambda: CampaignSpec.from_dict({"factors": {"seed": [1.5]}}),
     "factor 'seed': values must be an integer >= 0, got 1.5"),
    (lambda: CampaignSpec.from_dict({"factors": {"reference_gain": ["1,2,3"]}}),
     "factor 'reference_gain': need 1 or 2 finite values, got '1,2,3'"),
    (lambda: CampaignSpec.from_dict({"mode": "grid", "samples": 10}),
     "campaign samples is for mode: random (a grid crosses all levels)"),
    (lambda: CampaignSpec.from_dict({"factors": {"delay": ["csv:/no/such/trace.csv"]}}),
     "cannot read delay trace /no/such/trace.csv: [Errno 2] No such file or directory: "
     "'/no/such/trace.csv'"),
    (lambda: CampaignSpec.from_dict({"factors": ["kr"]}),
     "campaign factors must be a mapping of factor names to values"),
    (lambda: run_campaign(TINY, "campaign.parquet", chunk=0),
     "chunk must be an integer >= 1, got 0"),
    # falsification search
    (lambda: nuno_space(segments=0), "segments must be an integer >= 1, got 0"),
    (lambda: search(nuno_space(), objective="chaos"),  # type: ignore[arg-type]
     "objective must be one of energy_growth, error_growth, energy, got 'chaos'"),
    (lambda: search(nuno_space(), method="annealing"),  # type: ignore[arg-type]
     "search method must be 'cma' or 'random', got 'annealing'"),
]


@pytest.mark.parametrize(("call", "message"), API_CASES)
def test_api_bad_input_raises_the_exact_value_error(tmp_path, monkeypatch, call, message):
    monkeypatch.chdir(tmp_path)
    with pytest.raises(ValueError) as error:
        call()
    assert str(error.value) == message
    assert "\n" not in message


def test_there_are_at_least_25_cases():
    assert len(CLI_CASES) + len(API_CASES) >= 50
