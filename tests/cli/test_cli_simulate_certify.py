"""The ``teleopkit`` command line, run as a user would (a real subprocess)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pandas as pd
import pytest

REQUIRED = ["t", "ql_1", "ql_2", "qr_1", "qr_2", "theta_1", "theta_2", "Tl", "Tr", "e_track_1",
            "e_track_2", "e_damp_1", "e_damp_2"]


def teleopkit(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "teleopkit.cli", *args], capture_output=True,
                          text=True, timeout=300)


def test_simulate_writes_csv_and_figure(tmp_path):
    out, png = tmp_path / "run.csv", tmp_path / "run.png"
    done = teleopkit("simulate", "--kr", "10", "--br", "30", "--duration", "2",
                     "--delay", "constant:0.3", "--out", str(out), "--plot", str(png))
    assert done.returncode == 0, done.stderr
    table = pd.read_csv(out)
    assert set(REQUIRED) <= set(table.columns)
    assert len(table) == 201 and table["Tl"].eq(0.3).all()
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_simulate_reads_a_delay_trace(tmp_path):
    trace = tmp_path / "trace.csv"
    trace.write_text("t,delay\n0,0.1\n1,0.4\n")
    out = tmp_path / "run.csv"
    done = teleopkit("simulate", "--kr", "10,12", "--br", "30", "--duration", "1",
                     "--delay", f"csv:{trace}", "--out", str(out))
    assert done.returncode == 0, done.stderr
    table = pd.read_csv(out)
    assert table["Tl"].iloc[-1] == pytest.approx(0.4)
    assert table["Kr_2"].eq(12).all()


@pytest.mark.parametrize(("args", "needle"), [
    (["--kr", "-1", "--br", "30"], "--kr"),
    (["--kr", "nan", "--br", "30"], "--kr"),
    (["--kr", "10", "--br", "1,2,3"], "--br"),
    (["--kr", "10", "--br", "30", "--dt", "0"], "--dt"),
    (["--kr", "10", "--br", "30", "--dt", "-0.001"], "--dt"),
    (["--kr", "10", "--br", "30", "--duration", "0"], "duration"),
    (["--kr", "10", "--br", "30", "--delay", "csv:/no/such/file.csv"], "cannot read"),
    (["--kr", "10", "--br", "30", "--delay", "warp:3"], "unknown delay spec"),
    (["--kr", "10", "--br", "30", "--delay", "constant:-0.5"], "non-negative"),
    (["--kr", "10"], "--br"),
])
def test_bad_input_exits_2_with_one_line(tmp_path, args, needle):
    done = teleopkit("simulate", *args, "--out", str(tmp_path / "x.csv"))
    assert done.returncode == 2
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and needle in lines[0], done.stderr
    assert "Traceback" not in done.stderr


def test_malformed_trace_exits_2(tmp_path):
    trace = tmp_path / "bad.csv"
    trace.write_text("t,delay\n1,0.1\n0,0.2\n")
    done = teleopkit("simulate", "--kr", "10", "--br", "30", "--delay", f"csv:{trace}",
                     "--out", str(tmp_path / "x.csv"))
    assert done.returncode == 2 and "strictly increasing" in done.stderr


def test_certify_nuno_certified_and_json(tmp_path):
    done = teleopkit("certify", "--kr", "5:10", "--br", "30:60", "--method", "nuno", "--json")
    assert done.returncode == 0, done.stderr
    import json

    payload = json.loads(done.stdout)
    assert payload["certified"] is True and payload["method"] == "nuno"
    assert payload["gain_variation"] == "frozen"
    assert payload["delay_margin"] == pytest.approx((10 * 30 / (25 * 10)) ** 0.5)
    assert len(payload["polytope"]["G"]) == len(payload["polytope"]["h"])


def test_certify_not_certified_names_the_violation():
    done = teleopkit("certify", "--kr", "1:50", "--br", "1:150", "--method", "nuno")
    assert done.returncode == 1
    assert "NOT CERTIFIED" in done.stdout and "joint 1 at K_r = 50, B_r = 1" in done.stdout
    # the answer ends by naming the documentation page where its gain class is explained (by
    # title, not by a source path an installed user does not have), and that page exists
    assert done.stdout.rstrip().endswith('the "What is certified" page of the teleopkit '
                                         'documentation')
    page = Path(__file__).resolve().parents[2] / "docs" / "certified.rst"
    assert page.read_text().startswith("What is certified\n")


@pytest.mark.parametrize(("args", "needle"), [
    (["--kr", "50:1", "--br", "1:150"], "inverted"),
    (["--kr", ":", "--br", "1:150"], "--kr"),
    (["--kr", "1:5", "--br", "-1:150"], "non-negative"),
    (["--kr", "1:5", "--br", "nan:150"], "finite"),
    (["--kr", "1:5", "--br", "1:150", "--tl-max", "0"], "--tl-max"),
    (["--kr", "1:5", "--br", "1:150", "--tr-max", "-1"], "--tr-max"),
    (["--kr", "1:5", "--br", "1:150", "--kl", "-3"], "--kl"),
    (["--kr", "1:5", "--br", "1:150", "--method", "magic"], "--method"),
    (["--kr", "1:5", "--br", "1:150", "--gain-variation", "rate:-2"], "rate"),
    (["--kr", "1:5", "--br", "1:150", "--gain-variation", "sometimes"], "gain variation"),
    (["--kr", "1:5", "--br", "1:150", "--gain-variation", "switching"], "not switching gains"),
])
def test_certify_bad_input_exits_2(args, needle):
    done = teleopkit("certify", *args)
    assert done.returncode == 2
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and needle in lines[0], done.stderr


def test_simulate_warns_when_the_delays_exceed_what_its_gains_are_certified_for(tmp_path):
    done = teleopkit("simulate", "--kr", "10", "--br", "30", "--duration", "2", "--delay",
                     "constant:1.5", "--out", str(tmp_path / "run.csv"))
    assert done.returncode == 0, done.stderr
    assert done.stderr.strip() == ("warning: the delays reached 1.5 s; these gains are certified "
                                   "(closed form, constant gains) for delays up to 1.095 s only, "
                                   "so this run is outside every certificate")
    quiet = teleopkit("simulate", "--kr", "10", "--br", "30", "--duration", "1", "--delay",
                      "constant:0.5", "--out", str(tmp_path / "run.csv"))
    assert quiet.returncode == 0 and quiet.stderr == ""


@pytest.mark.parametrize(("args", "needle"), [
    (["simulate", "--kr", "10", "--br", "30", "--out", "/proc/x.csv"],
     "cannot write /proc/x.csv: "),
    (["simulate", "--kr", "10", "--br", "30", "--out", "OK", "--plot", "/proc/x.png"],
     "cannot write /proc/x.png: "),
    (["reproduce", "--out", "/proc/teleopkit-out"], "cannot write in /proc: "),
    (["train", "--out", "/proc/teleopkit-out"], "cannot write in /proc: "),
    (["campaign", "SPEC", "--out", "/proc/x.csv"], "cannot write /proc/x.csv: "),
    (["certify", "--kr", "0:0", "--br", "1:5"], "K_r of joint 1 is 0 everywhere in the box"),
])
def test_outputs_are_probed_before_any_work(tmp_path, args, needle):
    spec = tmp_path / "spec.json"
    spec.write_text('{"samples": 1, "duration": 0.1}')
    args = [str(tmp_path / "ok.csv") if a == "OK" else str(spec) if a == "SPEC" else a
            for a in args]
    done = teleopkit(*args)
    lines = done.stderr.strip().splitlines()
    assert done.returncode == 2 and len(lines) == 1 and needle in lines[0], done.stderr
    assert "Errno" not in lines[0] and list(tmp_path.iterdir()) == [spec]


def test_ctrl_c_exits_130_with_one_line(monkeypatch, capsys):
    from teleopkit.cli import main

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr("teleopkit.certification.certify_all", interrupted)
    assert main(["certify", "--kr", "1:5", "--br", "10:20"]) == 130
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("teleopkit: interrupted")


def test_certify_prints_the_closed_form_first_and_keeps_the_proven_set_on_ctrl_c():
    """Ctrl-C reaches the whole foreground process group: the workers as well as the CLI."""
    import os
    import signal

    def interruptible() -> None:
        # a test run started in the background (``pytest &``) ignores SIGINT, and so would the
        # command it starts: give the command the disposition of a terminal's foreground job
        signal.signal(signal.SIGINT, signal.SIG_DFL)

    process = subprocess.Popen([sys.executable, "-m", "teleopkit.cli", "certify", "--kr", "5:10",
                                "--br", "30:60", "--method", "lmi", "--no-cache",
                                "--workers", "2"],
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                               start_new_session=True, preexec_fn=interruptible)
    assert process.stdout is not None
    seen = []
    for line in process.stdout:
        seen.append(line)
        if line.startswith("LMI: proven so far"):
            os.killpg(process.pid, signal.SIGINT)
            break
    out, err = process.communicate(timeout=120)
    assert seen[0].startswith("plant: local arm l [0.38, 0.38] m")  # the answer names the plant
    assert seen[1].startswith("closed form (instant") and any("[nuno] CERTIFIED" in s for s in seen)
    assert process.returncode == 130
    assert out.startswith("interrupted: the best set proven so far")
    assert "[lmi] CERTIFIED for frozen gains" in out and "delay margin    not searched" in out
    assert err.strip().splitlines() == [
        "teleopkit: interrupted (finished rounds, chunks and proven sets are kept)"]


def error_of(capsys: pytest.CaptureFixture[str], *args: str) -> str:
    """Run the command line in this process; the one line it says on standard error (exit 2)."""
    from teleopkit.cli import main

    code = main(list(args))
    lines = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(lines) == 1, lines
    return lines[0].removeprefix("teleopkit: error: ")


@pytest.mark.parametrize("command", ["certify", "falsify"])
@pytest.mark.parametrize("variation", ["tank:nan", "tank:nanrad", "rate:nan", "scheduled:nan"])
def test_nan_in_a_gain_class_is_refused_quoting_what_was_typed(capsys, command, variation):
    number = variation.partition(":")[2]
    line = error_of(capsys, command, "--kr", "5:10", "--br", "30:60", "--gain-variation",
                    variation)
    assert line == (f"Invalid value for '--gain-variation': gain variation {variation!r}: "
                    f"{number!r} is not a number")


@pytest.fixture
def delay_floor(tmp_path: Path) -> Path:
    """The paper's setup with a backward delay of at least 50 ms."""
    from teleopkit.setup import paper_setup_path

    text = paper_setup_path().read_text().replace("backward: {min: 0.0,", "backward: {min: 0.05,")
    path = tmp_path / "floor.yaml"
    path.write_text(text)
    return path


@pytest.mark.parametrize(("args", "message"), [
    (["--tl-max", "nan"], "Invalid value for '--tl-max': nan is not a finite number"),
    (["--tr-max", "nan"], "Invalid value for '--tr-max': nan is not a finite number"),
    (["--tr-max", "inf"], "Invalid value for '--tr-max': inf is not a finite number"),
    (["--tl-min", "nan"], "Invalid value for '--tl-min': nan is not a finite number"),
    (["--kl", "nan"], "Invalid value for '--kl': nan is not a finite number"),
    (["--tl-min", "0.5", "--tl-max", "0.2"],
     "Invalid value for '--tl-min': the minimum delay T_l_min = 0.5 s is not below the bound "
     "T_l* = 0.2 s"),
    (["--setup", "FLOOR", "--tr-max", "0.01"],
     "Invalid value for '--tr-max': the minimum delay T_r_min = 0.05 s is not below the bound "
     "T_r* = 0.01 s"),
])
def test_certify_blames_the_option_that_is_wrong(capsys, delay_floor, args, message):
    args = [str(delay_floor) if a == "FLOOR" else a for a in args]
    assert error_of(capsys, "certify", "--kr", "5:10", "--br", "30:60", *args) == message


@pytest.mark.parametrize(("args", "message"), [
    (["--tl-max", "nan"], "Invalid value for '--tl-max': nan is not a finite number"),
    (["--duration", "0.105"], "Invalid value for '--duration': duration 0.105 s is not a whole "
                              "number of control periods of 0.01 s"),
])
def test_falsify_refuses_what_it_cannot_run_as_given(capsys, args, message):
    assert error_of(capsys, "falsify", "--kr", "5:10", "--br", "30:60", *args) == message


ONE_JOINT = """\
plant: {local_arm: {lengths: [0.3], masses: [1]}}
network:
  forward: {min: 0, max: 0.5, profile: "constant:0.3"}
  backward: {min: 0, max: 0.5, profile: "constant:0.1"}
operator: {motion: still}
start: rest
"""


def test_simulate_asks_a_one_joint_setup_for_one_value(tmp_path, capsys):
    setup = tmp_path / "one.yaml"
    setup.write_text(ONE_JOINT)
    line = error_of(capsys, "simulate", "--setup", str(setup), "--kr", "10,20", "--br", "30",
                    "--out", str(tmp_path / "x.csv"))
    assert line == "Invalid value for '--kr': needs 1 value (the setup has one joint), got 2"


@pytest.mark.parametrize(("args", "title"), [
    (["--setup", "ONE"], "delays (forward / backward) constant:0.3 / constant:0.1"),
    (["--setup", "ONE", "--delay", "constant:0.2"], "delay constant:0.2"),
    ([], "delay paper (the paper's profile scaled by this seed's delay scales)"),
])
def test_the_figure_names_the_delays_of_both_directions(tmp_path, monkeypatch, args, title):
    import teleopkit.plots as plots
    from teleopkit.cli import main

    (tmp_path / "one.yaml").write_text(ONE_JOINT)
    titles = []
    monkeypatch.setattr(plots, "save_run_figure",
                        lambda table, path, title="": titles.append(title))
    args = [str(tmp_path / "one.yaml") if a == "ONE" else a for a in args]
    assert main(["simulate", "--kr", "10", "--br", "30", "--duration", "1.5", *args, "--out",
                 str(tmp_path / "x.csv"), "--plot", str(tmp_path / "x.png")]) == 0
    assert titles == [f"K_r = [10.0], B_r = [30.0], {title}"]


def test_the_getting_started_page_shows_what_certify_prints():
    page = Path(__file__).resolve().parents[2] / "docs" / "getting_started.rst"
    after = page.read_text().split("   $ teleopkit certify --kr 5:10 --br 30:60\n", 1)[1]
    shown = []
    for line in after.splitlines():
        if line and not line.startswith("   "):
            break
        shown.append(line.removeprefix("   "))
    done = teleopkit("certify", "--kr", "5:10", "--br", "30:60")
    assert done.returncode == 0
    assert "\n".join(shown).strip("\n") == done.stdout.strip("\n")


def test_certify_refuses_plants_it_cannot_certify_together_before_printing(tmp_path, capsys):
    """The trial's fleet: plant 2 has B_l = 5; the plant line went out before the refusal,
    which did not say how to certify one plant. A file per plant does."""
    import yaml

    from teleopkit.cli import main
    from teleopkit.setup import paper_setup_path

    data = yaml.safe_load(paper_setup_path().read_text())
    other = {**data["plant"], "local_gains": {"stiffness": [25.0, 25.0], "damping": [5.0, 5.0]}}
    files = {name: tmp_path / f"{name}.yaml" for name in ("fleet", "plant2")}
    files["fleet"].write_text(yaml.safe_dump({**data, "plant": [data["plant"], other]}))
    files["plant2"].write_text(yaml.safe_dump({**data, "plant": other}))
    box = ["--kr", "1:20", "--br", "10:100"]
    assert main(["certify", "--setup", str(files["fleet"]), *box]) == 2
    assert capsys.readouterr() == ("", (
        "teleopkit: error: Invalid value for '--setup': the closed form certifies another set "
        "for plant 2 (its local gains B_l [5, 5] against [10, 10]) than for plant 1, so no one "
        "certificate covers the plants: write a setup file per plant (its plant entry alone) "
        "and certify each\n"))
    assert main(["certify", "--setup", str(files["plant2"]), *box]) in (0, 1)
    assert capsys.readouterr().out.startswith("plant: ")


@pytest.mark.parametrize("command", ["simulate", "evaluate"])
def test_the_delay_help_says_what_each_shape_does_to_the_two_channels(capsys, command):
    from teleopkit.cli import main

    assert main([command, "--help"]) == 0
    text = " ".join(capsys.readouterr().out.split())
    for words in ("sine:MEAN:AMP:FREQ (FREQ in Hz; the backward channel's phase shifted by a "
                  "quarter period)", "switching:LOW:HIGH:DWELL (each DWELL at LOW or HIGH, the "
                  "two channels drawn independently)", "csv:PATH (the same trace on both "
                  "channels)"):
        assert words in text
