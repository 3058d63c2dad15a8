"""Robustness campaigns: grid and random expansion, Dask execution, resume, bad specs."""

from __future__ import annotations

import json
import os
import re
import signal
import subprocess
import sys
import time
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pandas as pd
import pytest

import teleopkit as tk
import teleopkit.robustness.campaign as campaign
from teleopkit.cli import main
from teleopkit.delays import (
    ConstantDelay,
    FourierDelay,
    PiecewiseDelay,
    SinusoidalDelay,
    SquareWaveDelay,
    SwitchingDelay,
    scale_delay,
    stack_delays,
)
from teleopkit.rl.policy import GainPolicy
from teleopkit.robustness.campaign import run_campaign
from teleopkit.robustness.chunks import METRIC_COLUMNS, plan_chunks
from teleopkit.robustness.factors import FACTORS
from teleopkit.robustness.spec import CampaignSpec
from teleopkit.sim.scenarios import sample_reference_gains

TINY = {"duration": 1.0, "factors": {"delay": ["paper", "constant:0.3"], "kr": [10, 50],
                                     "joint_stiffness": [100, 60], "seed": [0, 1]}}
"""Sixteen scenarios; the paper's delays (up to 1 s) are shorter than these seeds' 1 s runs."""
KR_ONLY = {"duration": 0.2, "factors": {"kr": [10, 20, 30], "delay": "constant:0.05"}}
"""Three scenarios (the bad-input suite's ``TINY``), for the run without Dask."""


def without_timing(table: pd.DataFrame) -> pd.DataFrame:
    return table.drop(columns=["wall_time"])


# --- specs and expansion ---------------------------------------------------------------------


def test_grid_crosses_all_levels_with_seed_innermost():
    spec = CampaignSpec.from_dict({"factors": {
        "kr": [5, 10], "delay": ["constant:0.2", "paper"], "seed": {"range": [0, 3]},
        "bl": {"linspace": [8, 12, 3]}}})
    table = spec.expand()
    assert spec.size == len(table) == 2 * 2 * 3 * 3
    assert list(table.columns) == ["scenario", *FACTORS]
    assert table["scenario"].tolist() == list(range(36))
    assert table["seed"].tolist()[:3] == [0, 1, 2]
    assert table.drop_duplicates(list(FACTORS)).shape[0] == 36
    assert set(table["bl"]) == {8.0, 10.0, 12.0}
    assert (table["br"] == FACTORS["br"].default).all()
    assert (table["reference_gain"] == "random").all()


def test_random_campaign_is_seeded_and_factors_draw_independently():
    data = {"mode": "random", "samples": 50, "seed": 3,
            "factors": {"kr": {"uniform": [1, 20]}, "br": {"loguniform": [10, 100]},
                        "delay": ["paper", "constant:0.5"]}}
    first, again = (CampaignSpec.from_dict(data).expand() for _ in range(2))
    pd.testing.assert_frame_equal(first, again)
    assert first["kr"].between(1, 20).all() and first["br"].between(10, 100).all()
    assert set(first["delay"]) == {"paper", "constant:0.5"}
    assert first["seed"].nunique() == 50
    other = CampaignSpec.from_dict({**data, "seed": 4}).expand()
    assert not np.allclose(first["kr"], other["kr"])
    more = CampaignSpec.from_dict({**data, "factors": {**data["factors"], "kl": [20, 30]}})
    np.testing.assert_array_equal(more.expand()["kr"], first["kr"])


def test_spec_files_in_yaml_json_and_toml_agree(tmp_path):
    (tmp_path / "a.yaml").write_text("duration: 5\nfactors:\n  kr: [5, 10]\n  seed: 2\n")
    (tmp_path / "a.json").write_text(json.dumps({"duration": 5,
                                                 "factors": {"kr": [5, 10], "seed": 2}}))
    (tmp_path / "a.toml").write_text("duration = 5\n[factors]\nkr = [5, 10]\nseed = 2\n")
    specs = [CampaignSpec.from_file(tmp_path / f"a.{ext}") for ext in ("yaml", "json", "toml")]
    assert specs[0].to_dict() == specs[1].to_dict() == specs[2].to_dict()
    assert CampaignSpec.from_dict(specs[0].to_dict(), specs[0].base_dir) == specs[0]


def test_chunks_group_teleoperators_and_cover_every_scenario():
    table = CampaignSpec.from_dict(TINY).expand()
    chunks = plan_chunks(table, 3)
    ids = np.concatenate(chunks)
    assert sorted(ids) == list(range(len(table))) and len(chunks) == 6
    stiffness = table.set_index("scenario")["joint_stiffness"]
    assert [stiffness[c].nunique() for c in chunks].count(2) <= 1


def test_delay_combinators_keep_every_scenario_in_its_column():
    profiles = [FourierDelay(0.7), ConstantDelay(0.2), SinusoidalDelay(0.5, 0.1, 1.0),
                FourierDelay(0.9), SwitchingDelay(0.0, 0.4, 0.05, "extremes", 3),
                ConstantDelay(0.1)]
    t = np.linspace(0.0, 3.0, 301)
    expected = np.column_stack([p.sample(t)[:, 0] for p in profiles])
    stacked = stack_delays(profiles)
    np.testing.assert_array_equal(stacked.sample(t), expected)
    assert stacked.bound == pytest.approx(max(p.bound for p in profiles))
    for profile in profiles:
        np.testing.assert_allclose(scale_delay(profile, 0.5).sample(t), 0.5 * profile.sample(t))
    piecewise = PiecewiseDelay([[0.0, 1.0, 2.0]], [[0.1, 0.9, 0.3]], 1.0)
    assert piecewise.sample(np.array([0.5, 1.0, 2.5]))[:, 0].tolist() == [0.1, 0.9, 0.3]
    square = SquareWaveDelay([0.0], [1.0], [0.5], [0.0], 1.0)
    assert square.sample(np.array([0.1, 0.6, 1.1]))[:, 0].tolist() == [0.0, 1.0, 0.0]


# --- running -----------------------------------------------------------------------------------


def test_a_row_reproduces_simulate_from_its_own_columns(tmp_path):
    table = run_campaign({"duration": 1.0, "factors": {
        "delay": ["paper", "switching:0:0.8:0.05"], "kr": [10, 40], "seed": [4]}},
        tmp_path / "r.parquet", client="synchronous", chunk=3)
    for row in table.itertuples():
        run = tk.simulate((row.kr, row.br), duration=1.0, delay=row.delay, seed=row.seed)
        norm = np.linalg.norm(run[["e_track_1", "e_track_2"]].to_numpy(), axis=1)
        rms = np.sqrt(np.trapezoid(norm**2, run["t"]) / 1.0)
        assert row.rms_track == pytest.approx(rms, rel=1e-12)
        assert row.max_track == pytest.approx(norm.max(), rel=1e-12)
        drawn = sample_reference_gains(np.random.default_rng(row.seed), 1)[0]
        assert [row.G_1, row.G_2] == drawn.tolist()


def test_local_cluster_and_synchronous_scheduler_give_identical_rows(tmp_path):
    trace = tmp_path / "trace.csv"
    trace.write_text("t,delay\n0,0.2\n0.3,0.6\n4,0.4\n")
    spec = {**TINY, "factors": {**TINY["factors"],
                                "delay": ["paper", "constant:0.3", f"csv:{trace}"]}}
    sync = run_campaign(spec, tmp_path / "sync.parquet", client="synchronous", chunk=5)
    local = run_campaign(spec, tmp_path / "local.csv", client=None, workers=1, chunk=5)
    pd.testing.assert_frame_equal(without_timing(sync), without_timing(local))
    assert list(sync.columns[-len(METRIC_COLUMNS):]) == list(METRIC_COLUMNS)
    saved = pd.read_parquet(tmp_path / "sync.parquet")
    pd.testing.assert_frame_equal(saved, sync)
    assert len(pd.read_csv(tmp_path / "local.csv")) == len(sync) == 24
    assert sync.loc[sync["delay"].str.startswith("csv:"), "delay_bound"].eq(0.6).all()
    assert not sync["diverged"].any()


def test_campaign_runs_synchronously_without_dask(tmp_path, monkeypatch):
    import sys

    monkeypatch.setitem(sys.modules, "distributed", None)  # import distributed now fails
    monkeypatch.setitem(sys.modules, "dask", None)
    table = run_campaign(KR_ONLY, tmp_path / "o.csv", client="synchronous", chunk=2)
    assert len(table) == 3


def test_unstable_gains_are_flagged_as_diverged(tmp_path):
    table = run_campaign({"duration": 30.0, "factors": {"delay": "constant:1", "kr": [10, 50],
                                                        "br": [30, 1]}},
                         tmp_path / "d.parquet", client="synchronous")
    flags = table.set_index(["kr", "br"])["diverged"]
    assert flags[(50.0, 1.0)] and not flags[(10.0, 30.0)]


def test_resume_runs_only_missing_or_damaged_chunks(tmp_path, monkeypatch):
    out = tmp_path / "res.parquet"
    full = run_campaign(TINY, out, client="synchronous", chunk=3)
    chunks = out.with_name(out.name + ".chunks")
    (chunks / "chunk-000001.parquet").unlink()
    (chunks / "chunk-000004.parquet").write_bytes(b"not parquet")
    (chunks / ".chunk-000002.parquet.deadbeef.tmp").write_bytes(b"partial write")
    calls = []
    original = campaign.simulate_chunk
    monkeypatch.setattr(campaign, "simulate_chunk",
                        lambda task, *rest: calls.append(task.chunk) or original(task, *rest))
    again = run_campaign(TINY, out, client="synchronous", chunk=3)
    assert sorted(calls) == [1, 4]
    pd.testing.assert_frame_equal(without_timing(again), without_timing(full))
    assert again["scenario"].is_unique and len(again) == 16


def test_an_interrupted_campaign_completes_on_resume(tmp_path, monkeypatch):
    out = tmp_path / "int.parquet"
    original = campaign.simulate_chunk
    calls = []

    def crash_on_third(task, *rest):
        calls.append(task.chunk)
        if len(calls) == 3:
            raise RuntimeError("simulated crash")
        return original(task, *rest)

    monkeypatch.setattr(campaign, "simulate_chunk", crash_on_third)
    with pytest.raises(RuntimeError, match="simulated crash"):
        run_campaign(TINY, out, client="synchronous", chunk=3)
    assert not out.exists()
    assert len(list(out.with_name(out.name + ".chunks").glob("chunk-*.parquet"))) == 2
    calls.clear()
    monkeypatch.setattr(campaign, "simulate_chunk",
                        lambda task, *rest: calls.append(task.chunk) or original(task, *rest))
    table = run_campaign(TINY, out, client="synchronous", chunk=3)
    assert len(calls) == 4 and sorted(calls) == sorted(set(calls))
    assert table["scenario"].tolist() == list(range(16))


def test_a_killed_campaign_process_resumes_without_duplicates(tmp_path):
    spec = tmp_path / "spec.json"
    spec.write_text(json.dumps({"duration": 0.5, "factors": {"kr": {"linspace": [5, 40, 30]},
                                                             "delay": "constant:0.1"}}))
    out = tmp_path / "kill.parquet"
    chunks = out.with_name(out.name + ".chunks")
    env = {**os.environ, "NUMBA_NUM_THREADS": "1"}
    process = subprocess.Popen([sys.executable, "-c", "import sys; from teleopkit.cli import main;"
                                " sys.exit(main(sys.argv[1:]))", "campaign", str(spec), "--out",
                                str(out), "--scheduler", "synchronous", "--chunk", "1"], env=env)
    deadline = time.monotonic() + 120
    while not list(chunks.glob("chunk-*.parquet")) and process.poll() is None:
        assert time.monotonic() < deadline
        time.sleep(0.02)
    process.send_signal(signal.SIGKILL)
    process.wait()
    before = {p.name: pd.read_parquet(p) for p in chunks.glob("chunk-*.parquet")}
    assert main(["campaign", str(spec), "--out", str(out), "--scheduler", "synchronous",
                 "--chunk", "1", "--resume"]) == 0
    table = pd.read_parquet(out)
    assert table["scenario"].tolist() == list(range(30))
    for name, part in before.items():
        pd.testing.assert_frame_equal(pd.read_parquet(chunks / name), part)


def _kill_a_busy_worker(client, chunks, running) -> tuple[int, int]:
    """SIGKILL a worker running a chunk once the first chunk is on disk: (pid, chunks then)."""
    pids = client.run(os.getpid)
    deadline = time.monotonic() + 60
    while not list(chunks.glob("chunk-*.parquet")) and not running.done():
        assert time.monotonic() < deadline
        time.sleep(0.01)
    busy = [address for address, keys in client.processing().items() if keys]
    assert busy, "the campaign ended before a worker could be killed"
    victim = pids[busy[0]]
    os.kill(victim, signal.SIGKILL)
    return victim, len(list(chunks.glob("chunk-*.parquet")))


def _kill_campaign(tmp_path, allowed_failures: int):
    """Run a 24-chunk campaign on 2 workers and kill one mid-way; return what is needed to check."""
    distributed = pytest.importorskip("distributed")
    import dask

    trace = tmp_path / "trace.csv"
    # scattered to every worker: must survive too
    trace.write_text("t,delay\n0,0.2\n0.3,0.6\n4,0.4\n")
    spec = {"duration": 4.0, "factors": {"kr": {"linspace": [5, 40, 12]},
                                         "delay": ["paper", f"csv:{trace}"]}}
    sync = run_campaign(spec, tmp_path / "sync.parquet", client="synchronous", chunk=1)
    out = tmp_path / "kill.parquet"
    chunks = out.with_name(out.name + ".chunks")
    # One SIGKILL makes each chunk in flight on that worker "suspicious" once; Dask gives up on a
    # chunk (KilledWorker) after allowed-failures + 1 deaths. The pool is entered first so that,
    # should the campaign hang, closing the client ends it.
    with (ThreadPoolExecutor(1) as pool,
          dask.config.set({"distributed.scheduler.allowed-failures": allowed_failures}),
          campaign.local_cluster(2) as cluster, distributed.Client(cluster) as client):
        running = pool.submit(run_campaign, spec, out, client=client, chunk=1)
        victim, finished_at_kill = _kill_a_busy_worker(client, chunks, running)
        error = running.exception(timeout=60)
        table = None if error else running.result()
        client.wait_for_workers(2, timeout=30)  # the nanny starts a replacement worker
        assert victim not in client.run(os.getpid).values()
    assert 1 <= finished_at_kill < len(sync)  # the kill hit a running campaign
    return spec, sync, out, table, error


def _check_complete(table, sync, out):
    assert table["scenario"].tolist() == list(range(len(sync)))
    pd.testing.assert_frame_equal(without_timing(table), without_timing(sync))
    pd.testing.assert_frame_equal(pd.read_parquet(out), table)
    files = sorted(out.with_name(out.name + ".chunks").glob("chunk-*.parquet"))
    assert [f.name for f in files] == [f"chunk-{k:06d}.parquet" for k in range(len(sync))]
    assert pd.concat(map(pd.read_parquet, files))["scenario"].sort_values().tolist() == list(
        range(len(sync)))


def test_a_killed_dask_worker_is_replaced_without_losing_or_duplicating_rows(tmp_path):
    _, sync, out, table, error = _kill_campaign(tmp_path, allowed_failures=3)
    assert error is None
    _check_complete(table, sync, out)


def test_a_chunk_dask_gives_up_on_stops_the_campaign_and_resume_finishes_it(tmp_path):
    spec, sync, out, _, error = _kill_campaign(tmp_path, allowed_failures=0)
    assert isinstance(error, campaign.CampaignInterrupted)
    message = str(error)
    assert "\n" not in message and "resume" in message and "tcp://" in message
    _check_complete(run_campaign(spec, out, client="synchronous", chunk=1, resume=True), sync, out)


def test_trained_policies_retune_the_gains_deterministically(tmp_path):
    policy = tmp_path / "policy.npz"
    GainPolicy.pretrained().save(policy)
    spec = {"duration": 3.0, "factors": {"controller": ["fixed", f"policy:{policy}"],
                                         "seed": [0, 1, 2]}}
    one = run_campaign(spec, tmp_path / "one.parquet", client="synchronous", chunk=1)
    six = run_campaign(spec, tmp_path / "six.parquet", client="synchronous", chunk=6)
    pd.testing.assert_frame_equal(without_timing(one).drop(columns="chunk"),
                                  without_timing(six).drop(columns="chunk"))
    fixed, tuned = (one[one["controller"] == c].reset_index(drop=True)
                    for c in ("fixed", f"policy:{policy}"))
    assert len(fixed) == len(tuned) == 3 and not one["diverged"].any()
    assert np.all(np.isfinite(tuned[list(METRIC_COLUMNS)].to_numpy(dtype=float)))
    assert not np.allclose(tuned["rms_track"], fixed["rms_track"])  # the policy acts


def test_a_changed_policy_file_is_another_campaign(tmp_path):
    policy = tmp_path / "policy.npz"
    GainPolicy.pretrained().save(policy)
    spec = CampaignSpec.from_dict({"factors": {"controller": [f"policy:{policy}"]}})
    before = spec.fingerprint()
    GainPolicy.load(policy).save(policy)  # same weights: same campaign
    assert spec.fingerprint() == before
    changed = GainPolicy.load(policy)
    changed.metadata["note"] = "retrained"
    changed.save(policy)
    assert spec.fingerprint() != before


def test_a_local_cluster_leaves_this_processes_numba_settings_alone():
    """Dask's nanny copies its spawn environment into this process; numba would then refuse
    to compile once its threads had started with another count."""
    pytest.importorskip("distributed")
    before = os.environ.get("NUMBA_NUM_THREADS")
    with campaign.local_cluster(1):
        pass
    assert os.environ.get("NUMBA_NUM_THREADS") == before


def test_resume_refuses_chunks_of_another_spec(tmp_path):
    out = tmp_path / "x.parquet"
    run_campaign(TINY, out, client="synchronous", chunk=8)
    with pytest.raises(ValueError, match="holds chunks of another campaign or chunk size"):
        run_campaign(TINY, out, client="synchronous", chunk=4)
    changed = {**TINY, "duration": 1.2}
    with pytest.raises(ValueError, match="holds chunks of another campaign"):
        run_campaign(changed, out, client="synchronous", chunk=8)
    assert len(run_campaign(changed, out, client="synchronous", chunk=8, resume=False)) == 16


def test_a_stiff_plant_runs_at_a_step_it_allows(tmp_path):
    # half the local arm's masses: the default step is refused above, 1.25 ms is stable
    data = {"duration": 0.3, "dt": 0.00125, "factors": {"local_mass_scale": [0.5],
                                                        "delay": "constant:0.1"}}
    table = run_campaign(data, tmp_path / "stiff.csv", client="synchronous")
    assert not table["diverged"].any()


def test_cli_campaign_writes_the_table_and_exits_0(tmp_path, capsys):
    spec = tmp_path / "c.yaml"
    spec.write_text("duration: 0.3\nfactors:\n  kr: [5, 10, 20]\n  delay: constant:0.1\n")
    out = tmp_path / "c.csv"
    assert main(["campaign", str(spec), "--out", str(out), "--scheduler", "synchronous"]) == 0
    assert "wrote 3 scenarios" in capsys.readouterr().out
    assert pd.read_csv(out)["kr"].tolist() == [5.0, 10.0, 20.0]


@pytest.mark.parametrize(("data", "message"), [
    ({"factors": {"kr": [-1]}}, "factor 'kr': values must be finite and >= 0, got -1"),
    ({"mode": "random"}, "campaign samples must be an integer >= 1, got 0"),
    ({"factors": {"kr": {"uniform": [1, 2]}}}, "factor 'kr': uniform draws need mode: random"),
    ({"durations": 3}, "unknown campaign setting 'durations'"),
    ({"factors": {"delay": ["warp:9"]}}, "unknown delay spec 'warp:9'"),
    ({"factors": {"controller": ["pid"]}}, "values must be 'fixed' or policy:PATH, got 'pid'"),
    ({"factors": {"controller": ["policy:/no/such/policy.npz"]}}, "no policy file"),
    ({"factors": {"controller": ["policy:" + __file__]}}, "is not a teleopkit policy file"),
    ({"factors": {"local_mass_scale": [1.0, 0.5]}},
     "local_mass_scale=0.5, kl=25, bl=10: dt = 2.5 ms is beyond the integrator's stability limit"),
    ({"factors": {"rotor_inertia": [0.1], "br": [30, 400]}},
     "rotor_inertia=0.1, remote_mass_scale=1, local_mass_scale=1, kl=25, bl=10: br = 400 is "
     "beyond what dt = 2.5 ms integrates stably on its motor (at most 135.5)"),
    ({"mode": "grid", "duration": 4, "factors": {"delay_scale": [5]}},
     "scenario 0 (delay paper, delay_scale 5, seed 0): the delay reaches 4.78189 s, not "
     "shorter than the 4 s run"),
    ({"duration": 2, "factors": {"delay": ["constant:0.5", "sine:1:1:0.5"], "seed": [3]}},
     "scenario 1 (delay sine:1:1:0.5, delay_scale 1, seed 3): the delay reaches 2 s, not "
     "shorter than the 2 s run; delays are in seconds: 2 milliseconds is written 2ms"),
])
def test_bad_specs_raise_one_line_value_errors(data, message, tmp_path):
    with pytest.raises(ValueError, match=re.escape(message)) as error:
        run_campaign(data, tmp_path / "bad.parquet", client="synchronous")
    assert "\n" not in str(error.value)


@pytest.mark.parametrize("scale", [1.9, 2.0, 2.1, 2.2])
def test_a_row_is_refused_exactly_when_simulate_refuses_its_run(scale, tmp_path):
    """The campaign checks each row's drawn delays as simulate checks its run's."""
    spec = CampaignSpec.from_dict({"duration": 2.0, "factors": {
        "delay_scale": [scale], "seed": {"range": [0, 4]}, "delay": ["paper", "constant:0.95"]}})
    refused = []
    for row in spec.expand().itertuples():
        drawn = tk.Setup.paper().scenarios(row.seed, 1, row.delay)  # what simulate draws
        delays = (scale_delay(drawn.forward, scale), scale_delay(drawn.backward, scale))
        try:
            tk.simulate((10.0, 30.0), duration=2.0, delay=delays, seed=row.seed)
        except ValueError as error:
            assert "not shorter than the 2 s run" in str(error)
            refused.append(row.scenario)
    if not refused:
        assert len(run_campaign(spec, tmp_path / "ok.csv", client="synchronous")) == 8
        return
    with pytest.raises(ValueError, match=rf"^scenario {refused[0]} \(delay "):
        run_campaign(spec, tmp_path / "refused.csv", client="synchronous")
    assert not list(tmp_path.iterdir())


def test_cli_campaign_refuses_delays_as_long_as_the_run_with_exit_2(tmp_path, capsys):
    spec = tmp_path / "spec.yaml"
    spec.write_text("mode: grid\nduration: 4\nfactors: {delay_scale: [5]}\n")
    code = main(["campaign", str(spec), "--out", str(tmp_path / "o.csv"), "--scheduler",
                 "synchronous"])
    err = capsys.readouterr().err
    assert code == 2
    assert err == ("teleopkit: error: scenario 0 (delay paper, delay_scale 5, seed 0): the delay "
                   "reaches 4.78189 s, not shorter than the 4 s run\n")  # no hint of ms: scaled
    assert sorted(p.name for p in tmp_path.iterdir()) == ["spec.yaml"]


def test_a_campaign_that_fails_before_its_first_chunk_leaves_nothing_behind(tmp_path,
                                                                             monkeypatch):
    import teleopkit.robustness.campaign as campaign

    def broken(*args, **kwargs):
        raise RuntimeError("the cluster went away")

    monkeypatch.setattr(campaign, "_execute", broken)
    out = tmp_path / "o.csv"
    with pytest.raises(RuntimeError, match="went away"):
        campaign.run_campaign(KR_ONLY, out, client="synchronous")
    assert sorted(p.name for p in tmp_path.iterdir()) == []  # no chunks, no manifest, no lock
