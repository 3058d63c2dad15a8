"""Bad inputs, table-driven: every one gives its exact, one-line error (exit 2 on the CLI).

CLI cases run ``teleopkit.cli.main([...])`` in-process and compare the captured standard error
with ``teleopkit: error: MESSAGE``; API cases compare ``str(ValueError)`` with MESSAGE. ``{tmp}``
in arguments and messages stands for the test's temporary directory.
"""

from __future__ import annotations

import dataclasses
import json
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from teleopkit.certification import certify_gains, load_certificate
from teleopkit.certification.gain_sets import GainBox
from teleopkit.cli import main
from teleopkit.delays import ConstantDelay, PiecewiseDelay, TraceDelay, parse_delay
from teleopkit.model.linearize import linearized_state_space
from teleopkit.model.params import ElasticJoints, PDGains, paper_setup
from teleopkit.rl.env import FlexTeleopConfig
from teleopkit.rl.evaluation import rollout
from teleopkit.rl.policy import GainPolicy
from teleopkit.robustness.adversary import SearchSpace
from teleopkit.robustness.campaign import run_campaign
from teleopkit.robustness.search import search
from teleopkit.robustness.spec import CampaignSpec
from teleopkit.sim.scenarios import Scenario, paper_scenarios
from teleopkit.sim.simulator import Simulator, simulate

TINY = {"duration": 0.2, "factors": {"kr": [10, 20, 30], "delay": "constant:0.05"}}
"""Runs shorter than the paper's delays: constant ones, shorter than every run here."""
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

def certificate_file(name: str, *args: str) -> Callable[[Path], None]:
    """Setup: ``teleopkit certify --json`` with extra options, written to a file."""
    def setup(tmp: Path) -> None:
        box = GainBox.uniform((1.0, 50.0), (1.0, 150.0))
        options = dict(zip(args[::2], args[1::2], strict=True))
        params = paper_setup()
        if "--kl" in options:
            params = dataclasses.replace(params, local_gains=PDGains.uniform(
                float(options["--kl"]), 10.0))
        bound = float(options.get("--tl-max", 1.0))
        certificate = certify_gains(params, box, bound, bound)
        (tmp / name).write_text(certificate.to_json())
    return setup


def tampered(tmp: Path) -> None:
    """Setup: a certificate whose polytope lost its closed-form rows and got a larger box."""
    data = certify_gains(paper_setup(), GainBox.uniform((1.0, 50.0), (1.0, 150.0))).to_dict()
    data["polytope"]["G"] = data["polytope"]["G"][:8]
    data["polytope"]["h"] = [500.0, 500.0, *data["polytope"]["h"][2:8]]
    data["polytope"]["labels"] = data["polytope"]["labels"][:8]
    (tmp / "t.json").write_text(json.dumps(data))


def pretrained(tmp: Path) -> None:
    """Setup: the shipped policy as ``p.npz``."""
    GainPolicy.pretrained().save(tmp / "p.npz")


CLI_CASES = [
    # simulate: numbers, shapes, delay specs, files
    (["simulate", "--kr", "-1", "--br", "30", "--out", "{tmp}/x.csv"], no_setup,
     "Invalid value for '--kr': must be finite and non-negative, got '-1'"),
    (["simulate", "--kr", "abc", "--br", "30", "--out", "{tmp}/x.csv"], no_setup,
     "Invalid value for '--kr': needs a number or two separated by a comma, got 'abc'"),
    (["simulate", "--kr", "10", "--br", "1,2,3", "--out", "{tmp}/x.csv"], no_setup,
     "Invalid value for '--br': needs 1 or 2 values (one per joint), got 3"),
    ([*SIM, "--duration", "0"], no_setup,
     "Invalid value for '--duration': duration must be positive and finite, got 0 s"),
    ([*SIM, "--duration", "0.015"], no_setup,
     "Invalid value for '--duration': duration 0.015 s is not a whole number of control "
     "periods of 0.01 s"),
    ([*SIM, "--dt", "0"], no_setup,
     "Invalid value for '--dt': 0.0 is not in the range x>0."),
    ([*SIM, "--seed", "-1"], no_setup,
     "Invalid value for '--seed': -1 is not in the range x>=0."),
    ([*SIM, "--delay", "warp:3"], no_setup,
     "Invalid value for '--delay': unknown delay spec 'warp:3'; use paper, constant:T, "
     "sine:MEAN:AMP:FREQ, switching:LOW:HIGH:DWELL or csv:PATH"),
    ([*SIM, "--delay", "constant:-0.5"], no_setup,
     "Invalid value for '--delay': constant delay must be non-negative, got [-0.5]"),
    ([*SIM, "--delay", "constant:500"], no_setup,
     "the delay reaches 500 s, not shorter than the 40 s run; delays are in seconds: 500 "
     "milliseconds is written 500ms (a trace column delay_ms)"),
    ([*SIM, "--delay", "constant:0.5x"], no_setup,
     "Invalid value for '--delay': constant delay must be a time such as 0.5, 0.5s or 500ms, "
     "got '0.5x'"),
    ([*SIM, "--delay", "csv:{tmp}/trace.csv"], write("trace.csv", "t,delay\n0,0.1\n0,0.2\n"),
     "Invalid value for '--delay': delay trace times must be strictly increasing"),
    ([*SIM, "--delay", "csv:{tmp}/trace.csv"],
     write("trace.csv", "t,delay\n1764806400.5,0.1\n1764806401.5,0.2\n"),
     "Invalid value for '--delay': delay trace starts at 1.76481e+09 s, after t = 0 where runs "
     "start: subtract its first time from its times"),
    ([*SIM, "--delay", "csv:{tmp}/trace.csv"], write("trace.csv", "t,delay\n0,0.1\n10,0.2\n"),
     "the delay trace ends at 10 s, before the 40 s run does: record a longer trace or shorten "
     "the run"),
    ([*SIM, "--delay", "csv:{tmp}/trace.csv"], write("trace.csv", "time,lag\n0,0.1\n1,0.2\n"),
     "Invalid value for '--delay': delay trace {tmp}/trace.csv has no delay column (delay or "
     "latency, optionally with _s, _ms or _us); its columns: time, lag"),
    (["simulate", "--kr", "10", "--br", "30"], no_setup, "Missing option '--out'."),
    (["simulate", "--kr", "10", "--br", "30", "--out", "/nonexistent/dir/x.csv"], no_setup,
     "Invalid value for '--out': directory /nonexistent/dir does not exist"),
    (["simulate", "--kr", "10", "--br", "30", "--out", "{tmp}/x.txt"], no_setup,
     "Invalid value for '--out': needs a file name ending in .csv, got 'x.txt'"),
    ([*SIM, "--plot", "/nonexistent/p.png"], no_setup,
     "Invalid value for '--plot': directory /nonexistent does not exist"),
    ([*SIM, "--plot", "{tmp}/runplot"], no_setup,
     "Invalid value for '--plot': needs a file name ending in .png, .pdf, .svg, .jpg, .jpeg, "
     ".tif, .tiff, .eps, .webp, got 'runplot'"),
    # certify: ranges, bounds, classes
    (["certify", "--kr", "5:1", "--br", "30:60"], no_setup, "--kr range is inverted (5.0 > 1.0)"),
    (["certify", "--kr", "a:b", "--br", "30:60"], no_setup,
     "--kr must be MIN:MAX with numbers, got 'a:b'"),
    ([*CERT, "--tl-max", "0"], no_setup,
     "Invalid value for '--tl-max': 0.0 is not in the range 0<x<=1000000.0."),
    ([*CERT, "--kl", "-3"], no_setup,
     "Invalid value for '--kl': -3.0 is not in the range x>0."),
    ([*CERT, "--gain-variation", "rate:x"], no_setup,
     "Invalid value for '--gain-variation': gain variation 'rate:x': 'x' is not a number"),
    ([*CERT, "--gain-variation", "rate:-1"], no_setup,
     "Invalid value for '--gain-variation': gain variation rate:R needs a positive finite rate, "
     "got -1"),
    ([*CERT, "--gain-variation", "tank:nan"], no_setup,
     "Invalid value for '--gain-variation': gain variation 'tank:nan': 'nan' is not a number"),
    ([*CERT, "--tl-max", "nan"], no_setup,
     "Invalid value for '--tl-max': nan is not a finite number"),
    (["evaluate", "--policy", "{tmp}/p.npz", "--duration", "4.005", "--out", "{tmp}/e"],
     pretrained, "Invalid value for '--duration': duration 4.005 s is not a whole number of "
                 "control periods of 0.01 s"),
    ([*CERT, "--gain-variation", "scheduled"], no_setup,
     "Invalid value for '--gain-variation': gain variation scheduled needs a number "
     "(scheduled:N), got 'scheduled'"),
    ([*CERT, "--gain-variation", "switching"], no_setup,
     "the closed form (nuno) covers frozen, scheduled:L and tank gains, not switching gains; "
     "certify those with the LMIs (method lmi)"),
    # certificates used elsewhere: bound to their plant and delays, re-checked when read
    (["evaluate", "--policy", "{tmp}/p.npz", "--certificate", "{tmp}/kl.json", "--out",
      "{tmp}/e"], lambda tmp: (pretrained(tmp), certificate_file("kl.json", "--kl", "1")(tmp)),
     "the certificate is for K_l = [1.0, 1.0], the plant has [25.0, 25.0]"),
    (["train", "--certificate", "{tmp}/short.json", "--out", "{tmp}/r"],
     certificate_file("short.json", "--tl-max", "0.05"),
     "the --certificate covers forward delays up to 0.05 s and the setup's network reaches 1 s: "
     "certify for the setup's delays (teleopkit certify --setup FILE --json) or give a --setup "
     "whose network stays within them"),
    (["train", "--certificate", "{tmp}/t.json", "--out", "{tmp}/r"], tampered,
     "Invalid value for '--certificate': {tmp}/t.json: the certificate's gain polytope is not "
     "the one its plant, box and delay bounds give (edited?)"),
    (["train", "--certificate", "{tmp}/none.json"], no_setup,
     "Invalid value for '--certificate': cannot read {tmp}/none.json: No such file or "
     "directory"),
    (["evaluate", "--policy", "{tmp}/bad.npz", "--out", "{tmp}/e"],
     write("bad.npz", "not a policy"),
     "Invalid value for '--policy': {tmp}/bad.npz is not a teleopkit policy file (not an .npz "
     "archive written by GainPolicy.save)"),
    (["evaluate", "--policy", "{tmp}/missing.npz"], no_setup,
     "Invalid value for '--policy': File '{tmp}/missing.npz' does not exist."),
    # train
    (["train", "--steps", "0"], no_setup,
     "Invalid value for '--steps': 0 is not in the range x>=1."),
    (["train", "--resume", "--out", "{tmp}/typo"], no_setup,
     "Invalid value for '--resume': no checkpoint in {tmp}/typo (checkpoint.pt); leave "
     "--resume out to start a run there"),
    (["train", "--out", "{tmp}/file"], write("file", "x"),
     "Invalid value for '--out': {tmp}/file is a file, not a directory"),
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
     "Invalid value for '--out': needs a file name ending in .parquet, .csv, got 'o.txt'"),
    (["campaign", "{tmp}/ok.yaml", "--out", "/nonexistent/o.csv"], OK_SPEC,
     "Invalid value for '--out': directory /nonexistent does not exist"),
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
    # falsify
    (["falsify", "--kr", "1:50", "--br", "1:150", "--budget", "1"], no_setup,
     "Invalid value for '--budget': 1 is not in the range x>=2."),
    (["falsify", "--kr", "1:50", "--br", "1:150", "--budget", "4", "--population", "16"],
     no_setup,
     "Invalid value for '--budget': 4 runs are fewer than one population of 16 (--population)"),
    (["falsify", "--kr", "1:50", "--br", "1:150", "--tl-max", "-1"], no_setup,
     "Invalid value for '--tl-max': -1.0 is not in the range x>0."),
    (["falsify", "--kr", "1:50", "--br", "1:150", "--objective", "storage"], no_setup,
     "the storage objective needs a scheduled:L or tank certificate, not frozen"),
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
    (lambda: load_certificate("not json"),
     "malformed gain certificate: Expecting value: line 1 column 1 (char 0)"),
    (lambda: load_certificate("{}"), "malformed gain certificate: 'box'"),
    (lambda: load_certificate(with_changes(polytope__h=[1.0, 2.0])),
     "malformed gain certificate: polytope has 10 normals, 2 offsets and 10 labels"),
    (lambda: load_certificate(with_changes(box__kr=[[5.0, 1.0], [1.0, 5.0]])),
     "malformed gain certificate: K_r range is inverted (5.0 > 1.0)"),
    (lambda: load_certificate(with_changes(polytope__G="oops")),
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
    (lambda: CampaignSpec.from_dict({"duration": 0.105}),
     "campaign duration 0.105 s is not a whole number of control periods of 0.01 s"),
    (lambda: FlexTeleopConfig(episode_length=4.005),
     "duration 4.005 s is not a whole number of control periods of 0.01 s"),
    (lambda: nuno_space(duration=0.105),
     "duration 0.105 s is not a whole number of control periods of 0.01 s"),
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
     "cannot read delay trace /no/such/trace.csv: No such file or directory"),
    (lambda: CampaignSpec.from_dict({"duration": 3, "factors": {"delay": [
        "csv:" + write_trace("t,delay\n0,0.1\n2.5,0.2\n")]}}),
     "factor 'delay': csv:trace.csv: the delay trace ends at 2.5 s, before the 3 s run does: "
     "record a longer trace or shorten the run"),
    (lambda: rollout(lambda obs: np.full((len(obs), 4), 10.0), 1,
                     config=FlexTeleopConfig(episode_length=1.0),
                     delay="csv:" + write_trace("t,delay\n0,0.1\n0.5,0.2\n")),
     "the delay trace ends at 0.5 s, before the 1 s run does: record a longer trace or shorten "
     "the run"),
    (lambda: CampaignSpec.from_dict({"factors": ["kr"]}),
     "campaign factors must be a mapping of factor names to values"),
    (lambda: run_campaign(TINY, "campaign.parquet", chunk=0),
     "chunk must be an integer >= 1, got 0"),
    # simulations, scenarios, linearisation
    (lambda: simulate((10.0, 30.0), duration=0.015),
     "duration 0.015 s is not a whole number of control periods of 0.01 s"),
    (lambda: simulate((10.0, 30.0), delay="constant:500"),
     "the delay reaches 500 s, not shorter than the 40 s run; delays are in seconds: 500 "
     "milliseconds is written 500ms (a trace column delay_ms)"),
    (lambda: simulate((10.0, 30.0), delay=True),
     "delay must be a spec string, a constant in seconds or a pair of delay profiles "
     "(forward, backward), got True"),
    (lambda: simulate((10.0, 30.0), delay=(ConstantDelay(0.1),)),
     "delay must be a spec string, a constant in seconds or a pair of delay profiles "
     "(forward, backward), got 1 item(s), not two delay profiles"),
    (lambda: simulate((10.0, 30.0), duration=1e12),
     None),  # the memory needed depends on the machine: checked by prefix below
    (lambda: paper_scenarios(0, batch=0),
     "batch must be a whole number of scenarios >= 1, got 0"),
    (lambda: linearized_state_space(paper_setup(), [1.0, 2.0, 3.0], 30.0),
     "K_r needs 1 or 2 values (one per joint), got shape (3,)"),
    # delays with units
    (lambda: TraceDelay.from_csv(write_trace("time_ms,lag\n0,1\n1,2\n")),
     "delay trace trace.csv has no delay column (delay or latency, optionally with _s, _ms or "
     "_us); its columns: time_ms, lag"),
    (lambda: TraceDelay.from_csv(write_trace("t,delay,latency\n0,1,1\n1,2,2\n")),
     "delay trace trace.csv has more than one delay column (delay or latency, optionally with "
     "_s, _ms or _us); its columns: t, delay, latency"),
    (lambda: TraceDelay.from_csv(write_trace("t,delay\n0,1\n1,2\n"), unit="min"),
     "delay trace unit must be one of s, ms, us, got 'min'"),
    (lambda: parse_delay("constant:1.5h"),
     "constant delay must be a time such as 0.5, 0.5s or 500ms, got '1.5h'"),
    # certificates bound to their plant and delays
    (lambda: certify_gains(paper_setup(), GainBox.uniform((1.0, 5.0), (30.0, 60.0))).check(
        dataclasses.replace(paper_setup(), joints=ElasticJoints((50.0, 50.0), (0.3, 0.3)))),
     "the certificate is for joint stiffness S_r = [100.0, 100.0], the plant has [50.0, 50.0]"),
    (lambda: certify_gains(paper_setup(), GainBox.uniform((1.0, 5.0), (30.0, 60.0)), 0.5,
                           0.5).check(paper_setup(), 0.5, 0.8),
     "the backward delay can reach 0.8 s, beyond the certificate's bound 0.5 s (delays in "
     "seconds: a value in milliseconds needs the ms unit)"),
    (lambda: load_certificate(with_changes(plant__local_gains={
        "stiffness": [1.0, 1.0], "damping": [10.0, 10.0]})),
     "the certificate's gain polytope is not the one its plant, box and delay bounds give "
     "(edited?)"),
    (lambda: load_certificate(with_changes(plant={})),
     "the certificate names no plant; certify again with this teleopkit"),
    # falsification search
    (lambda: nuno_space(segments=0), "segments must be an integer >= 1, got 0"),
    (lambda: search(nuno_space(), objective="chaos"),  # type: ignore[arg-type]
     "objective must be one of energy_growth, error_growth, energy, storage, got 'chaos'"),
    (lambda: search(nuno_space(), method="annealing"),  # type: ignore[arg-type]
     "search method must be 'cma' or 'random', got 'annealing'"),
]


@pytest.mark.parametrize(("call", "message"), API_CASES)
def test_api_bad_input_raises_the_exact_value_error(tmp_path, monkeypatch, call, message):
    monkeypatch.chdir(tmp_path)
    with pytest.raises(ValueError) as error:
        call()
    if message is None:  # the message holds machine-dependent sizes
        assert str(error.value).startswith("a run of 1e+12 s of 1 scenario(s) records 2.72e+07 "
                                           "GB, more than half the ")
        return
    assert str(error.value) == message
    assert "\n" not in message


def write_trace(text: str) -> str:
    """A trace file ``trace.csv`` in the working directory (the test's temporary one)."""
    Path("trace.csv").write_text(text)
    return "trace.csv"


def test_simulate_writes_nothing_when_an_output_is_bad(tmp_path):
    code = main(["simulate", "--kr", "10", "--br", "30", "--out", str(tmp_path / "x.csv"),
                 "--plot", "/nonexistent/p.png"])
    assert code == 2 and not (tmp_path / "x.csv").exists()


def test_a_run_too_large_for_the_disk_is_refused_up_front(tmp_path, capsys):
    code = main(["simulate", "--kr", "10", "--br", "30", "--duration", "1e12", "--out",
                 str(tmp_path / "x.csv")])
    err = capsys.readouterr().err
    assert code == 2 and err.startswith("teleopkit: error: Invalid value for '--out': the output "
                                        "would take about 5.94e+07 GB, more than the ")


def test_there_are_at_least_50_cases():
    assert len(CLI_CASES) + len(API_CASES) >= 50
