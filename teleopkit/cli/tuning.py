"""``teleopkit train``, ``evaluate`` and ``reproduce``: TD3 gain tuners and their comparison."""

from __future__ import annotations

import json
import sys
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

import click
from click.core import ParameterSource

from teleopkit.cli.options import (
    DELAY_SPECS,
    certificate_option,
    check_covers_setup,
    check_output_dir,
    check_setup_step,
    check_traces,
    delay_spec,
    dt_option,
    gain_variation,
    read_certificate,
    require_torch,
    run_duration,
    setup_option,
    single_thread,
)

if TYPE_CHECKING:
    from teleopkit.certification.gain_certificate import GainCertificate
    from teleopkit.rl.env import FlexTeleopConfig
    from teleopkit.rl.policy import GainPolicy
    from teleopkit.rl.recipes import TrainConfig
    from teleopkit.setup import Setup

__all__ = ["evaluate_command", "reproduce_command", "train_command"]


@click.command("train")
@click.option("--steps", type=click.IntRange(min=1), default=1_600_000, show_default=True,
              help="Transitions to collect over all environments (rounded up to whole "
                   "rounds: one episode of every environment).")
@click.option("--envs", type=click.IntRange(min=1), default=16, show_default=True,
              help="Scenarios simulated together.")
@click.option("--seed", type=click.IntRange(min=0), default=0, show_default=True,
              help="Master seed of the run.")
@click.option("--recipe", type=click.Choice(["paper", "fast"]), default="paper",
              show_default=True,
              help="Training recipe (teleopkit.rl.recipes.RECIPES): the paper's, 40 s "
                   "episodes, critics of the certified gains; or fast, 10 s training episodes "
                   "validated on 40 s ones, critics of the raw gains, a tanh output started "
                   "at the class's best constant gains (searched first, about half a minute; "
                   "faster and better on the training setup, far worse on starts it never "
                   "saw).")
@click.option("--out", type=click.Path(path_type=Path), default="runs/train", show_default=True,
              help="Directory for checkpoint.pt, train_log.csv, policy.npz, best_policy.npz, "
                   "config.json and certificate.json.")
@click.option("--resume", is_flag=True,
              help="Continue the run in --out with its recorded settings and certificate "
                   "(--steps may change the length).")
@click.option("--gain-variation", "variation", default=None, callback=gain_variation,
              help="Gain class to train under, on the closed form's certificate of the default "
                   "box (K_r in [1, 50], B_r in [1, 150]) for the delays the setup's network "
                   "reaches [default: the recipe's covering class, "
                   "teleopkit.rl.env.COVERING_CLASS].")
@click.option("--observation", type=click.Choice(["paper", "adaptive"]), default="paper",
              show_default=True,
              help="What the tuner observes: the paper's 7 values per joint, or the adaptive "
                   "observation (link velocity, deflection rate, levels of motion and errors, "
                   "the measured delay; no integrals: teleopkit.rl.features).")
@certificate_option
@dt_option
@setup_option
@click.pass_context
def train_command(ctx: click.Context, steps: int, envs: int, seed: int, recipe: str, out: Path,
                  resume: bool, variation: object, observation: str, certificate: Path | None,
                  dt: float, setup: Setup) -> None:
    """Train a TD3 gain tuner (checkpointed every episode; --resume continues exactly).

    Episodes draw their scenarios from the setup (--setup; the paper's by default): its
    plant, the delays of each direction of its network, its operator motions and starts.

    By default it trains under a class whose certificate covers every schedule the tuner plays
    (the certificate is recorded in the policy files, and evaluate uses it). The other settings
    are the recipe's (--recipe, teleopkit.rl.recipes.RECIPES): the paper's TD3 on 40 s
    episodes by default (learning rates 1e-3, discount 0.95), or the fast one (10 s training
    episodes, discount 0.99, the actor started at the best constant gains of its class for the
    setup); either keeps the best policy by its validation cost on 40 s
    episodes, and its first round explores with uniform random gains.
    """
    require_torch()
    from teleopkit.files import check_unlocked
    from teleopkit.rl.env import FlexTeleopConfig
    from teleopkit.rl.training import CHECKPOINT, LOCK, train

    check_output_dir(out, "--out")
    if certificate is not None and variation is not None:
        raise click.BadParameter("give a --certificate or a --gain-variation, not both",
                                 param_hint="'--gain-variation'")
    if resume and not (out / CHECKPOINT).is_file():
        raise click.BadParameter(f"no checkpoint in {out} ({CHECKPOINT}); leave --resume out "
                                 "to start a run there", param_hint="'--resume'")
    if not resume and (out / CHECKPOINT).exists():
        raise click.BadParameter(f"{out / CHECKPOINT} exists; pass --resume to continue it or "
                                 "choose another directory", param_hint="'--out'")
    check_unlocked(out / LOCK, str(out))  # before anything is printed
    settings = _training_config(ctx, out, resume, steps, envs, seed, recipe)
    check_traces(setup, max(settings.episode_length, settings.validation_length or 0.0),
                 "--setup")
    check_setup_step(setup, dt)
    env_config = FlexTeleopConfig(setup, observation=observation, dt=dt)
    chosen = _training_certificate(out, resume, variation, certificate, env_config)
    per_round = _round_steps(settings)
    if settings.total_steps % per_round:
        rounded = -(-settings.total_steps // per_round) * per_round
        click.echo(f"--steps {settings.total_steps} is rounded up to {rounded} transitions: "
                   f"whole rounds of {settings.num_envs} scenarios x "
                   f"{per_round // settings.num_envs} control periods", err=True)
        settings = replace(settings, total_steps=rounded)
    click.echo(f"training under {chosen.gain_variation} ({chosen.variation.describe()}) on the "
               "certified set of the box " + _box_text(chosen), err=True)
    single_thread()
    result = train(settings, out, resume=resume,
                   env_config=replace(env_config, certificate=chosen),
                   progress=sys.stderr.isatty())
    row = result.log.iloc[-1]
    click.echo(f"trained {int(row['step'])} steps under {chosen.gain_variation}; best "
               f"validation cost {result.log['validation_cost'].min():.5g}; policies in {out}")


def _box_text(certificate: GainCertificate) -> str:
    """The certificate's box, and whether the whole box or only its polytope is certified."""
    box = certificate.box
    ranges = ", ".join(f"K_r{i + 1} in [{box.kr[i][0]:g}, {box.kr[i][1]:g}], B_r{i + 1} in "
                       f"[{box.br[i][0]:g}, {box.br[i][1]:g}]" for i in range(box.n_joints))
    return ranges + ("" if certificate.certified else
                     " (the whole box is not certified: the safety layer projects onto its "
                     "certified polytope, shown by teleopkit certify)")


def _training_certificate(out: Path, resume: bool, variation: object,
                          certificate: Path | None, config: FlexTeleopConfig) -> GainCertificate:
    """The certificate to train under: the run's recorded one on resume, else the one asked for.

    A resumed run keeps its certificate; another one asked for on resume is refused by the
    checkpoint's settings check, which names it.
    """
    from teleopkit.certification.certifier import default_certificate
    from teleopkit.rl.env import COVERING_CLASS
    from teleopkit.rl.training import CERTIFICATE

    bounds = config.setup.network.reached_bounds
    from teleopkit.safety.factory import layer_for

    if certificate is not None:
        chosen = read_certificate(certificate)
    elif variation is not None or not (resume and (out / CERTIFICATE).is_file()):
        chosen = default_certificate(config.params, bounds, variation or COVERING_CLASS,
                                     config.setup.plants,  # type: ignore[arg-type]
                                     config.setup.ranges, config.setup.start)
    else:
        chosen = read_certificate(out / CERTIFICATE)
    whose = "the --certificate" if certificate is not None else "the run's certificate"
    check_covers_setup(chosen, config.setup, None, whose)
    layer_for(chosen)  # refuses a certificate whose set is not certified, before any work
    return chosen


def _round_steps(settings: TrainConfig) -> int:
    """Transitions of one round: an episode of the settings' length of every scenario."""
    from teleopkit.rl.env import FlexTeleopConfig

    return settings.num_envs * FlexTeleopConfig(episode_length=settings.episode_length).max_steps


def _recipe_of(settings: TrainConfig) -> str | None:
    """The name of the recipe the settings are (any length, scenarios, seed, warm-up), if any."""
    from teleopkit.rl.recipes import RECIPES

    free = ("total_steps", "num_envs", "seed", "learning_starts", "checkpoint_every")

    def kept(config: TrainConfig) -> dict[str, Any]:
        return {k: v for k, v in config.to_dict().items() if k not in free}

    return next((name for name, known in RECIPES.items() if kept(known) == kept(settings)), None)


def _training_config(ctx: click.Context, out: Path, resume: bool, steps: int, envs: int,
                     seed: int, recipe: str) -> TrainConfig:
    """The run's settings: recorded ones on resume (with the new length), else the recipe's.

    The warm-up (uniform random gains) is the first round, or the first half of a run of one
    round; a resumed run keeps the warm-up it was started with.
    """
    from teleopkit.rl.recipes import RECIPES, TrainConfig
    from teleopkit.rl.training import CONFIG

    if resume and (out / CONFIG).is_file():
        try:
            recorded = TrainConfig.from_dict(json.loads((out / CONFIG).read_text()))
        except (OSError, ValueError, TypeError, KeyError) as error:
            raise click.BadParameter(f"cannot read {out / CONFIG}: {error}",
                                     param_hint="'--resume'") from None
        for name, value in (("envs", envs), ("seed", seed)):
            given = ctx.get_parameter_source(name) is not ParameterSource.DEFAULT
            field = "num_envs" if name == "envs" else name
            if given and getattr(recorded, field) != value:
                raise click.BadParameter(f"the run in {out} has --{name} "
                                         f"{getattr(recorded, field)}; a resumed run keeps its "
                                         "settings (only --steps may change)",
                                         param_hint=f"'--{name}'")
        given = ctx.get_parameter_source("recipe") is not ParameterSource.DEFAULT
        trained_with = _recipe_of(recorded)
        if given and trained_with != recipe:
            had = f"--recipe {trained_with}" if trained_with else "settings of no recipe"
            raise click.BadParameter(f"the run in {out} has {had}; a resumed run keeps its "
                                     "settings (only --steps may change)", param_hint="'--recipe'")
        return replace(recorded, total_steps=steps)
    chosen = replace(RECIPES[recipe], total_steps=steps, num_envs=envs, seed=seed)
    per_round = _round_steps(chosen)
    warm_up = per_round if steps > per_round else max(envs, per_round // 2)
    return replace(chosen, learning_starts=warm_up)


class _PolicyFile(click.Path):
    """A policy file, or the name of a shipped policy (teleopkit.rl.policy.SHIPPED_POLICIES)."""

    def __init__(self) -> None:
        super().__init__(exists=True, dir_okay=False, path_type=Path)

    def convert(self, value: Any, param: click.Parameter | None,
                ctx: click.Context | None) -> Any:
        """A path as click checks it; a bare name (no directory, no suffix) as a policy name."""
        from teleopkit.rl.policy import resolve_policy

        if Path(value).name != str(value) or Path(value).suffix:
            return super().convert(value, param, ctx)
        try:
            return resolve_policy(str(value))
        except ValueError as error:
            self.fail(str(error), param, ctx)


@click.command("evaluate")
@click.option("--policy", "policy_files", required=True, multiple=True, type=_PolicyFile(),
              metavar="FILE|NAME",
              help="Policy file (policy.npz), or a shipped policy: covered (the TD3 tuner "
                   "trained under tank:3, whose certificate covers every schedule it plays), law "
                   "(the gain law searched for the mixed setup under tank:3) or paper (the "
                   "paper's tuner, trained under the frozen class); repeat for several "
                   "training seeds of one recipe (one row), or for another tuner of a class "
                   "the first policy's certificate covers (its own row, e.g. --policy covered "
                   "--policy law).")
@click.option("--scenarios", type=click.IntRange(min=1), default=32, show_default=True,
              help="Held-out scenarios.")
@click.option("--seed", type=click.IntRange(min=0), default=7_777, show_default=True,
              help="Seed of the held-out scenarios (teleopkit.rl.evaluation.EVAL_SEED).")
@click.option("--delay", default=None, callback=delay_spec,
              help=f"Delays of both channels in place of the setup's network, for example "
                   f"shapes training never saw: {DELAY_SPECS}.")
@click.option("--duration", type=float, default=40.0, show_default=True, callback=run_duration,
              help="Episode length [s] (a whole number of 10 ms control periods).")
@click.option("--out", type=click.Path(path_type=Path), default="runs/evaluate",
              show_default=True, help="Directory for per_scenario.csv, summary.csv and summary.md.")
@click.option("--certificate", type=click.Path(dir_okay=False, path_type=Path), default=None,
              help="Gain certificate (teleopkit certify --json) to run the policies under; it "
                   "must cover the class they were trained under [default: the certificate "
                   "recorded in the first policy file].")
@click.option("--fall-back/--no-fall-back", default=True, show_default=True,
              help="Let a gain law step aside for the best constant gains of its class on a "
                   "setup where they are cheaper on fresh scenarios of it (neither those they "
                   "were searched on nor the held-out ones); --no-fall-back runs it as searched.")
@dt_option
@setup_option
def evaluate_command(policy_files: tuple[Path, ...], scenarios: int, seed: int,
                     delay: str | None, duration: float, out: Path, certificate: Path | None,
                     fall_back: bool, dt: float, setup: Setup) -> int:
    """Compare TD3 policies with the best static gains and the other comparators.

    Every row runs on the same held-out scenarios drawn from the setup; policies of one kind
    and observation share a row (training seeds), another tuner (a gain law beside a TD3 tuner)
    has its own row, run with its own observation under the same certificate. The reference row
    "best static" is the best constant gains of the frozen class on the certificate's box,
    and the comparators of the policies' own class (best static gains, the tuned semi-active
    damping law, the tuner's open-loop mean schedule) are searched for this setup and
    certificate (a few minutes; reused from the policy file or the cache when they were
    searched for the same question). A gain law evaluated under a certificate with another
    set than the one it was searched under is moved onto it first: its start moves as the
    best constant gains of the setup move between the two sets (two searches, about a minute).
    A gain law steps aside on a setup where the best constant gains of its class are cheaper
    on 32 fresh scenarios of it (neither those the gains were searched on nor the held-out
    ones): its row then plays them, and a line says so (--no-fall-back runs it as searched).
    """
    from teleopkit.rl.comparison import (
        REFERENCE,
        as_run,
        compare,
        evaluation_config,
        report_preamble,
        schedule_label,
        tuner_rows,
    )
    from teleopkit.rl.evaluation import save_report, to_markdown
    from teleopkit.rl.law_search import stepped_aside
    from teleopkit.rl.policy import GainPolicy

    check_output_dir(out, "--out")
    check_traces(setup if delay is None else setup.with_delay(delay), duration,
                 "--setup" if delay is None else "--delay")
    policies = []
    for path in policy_files:
        try:
            policies.append(GainPolicy.load(path))
        except ValueError as error:
            raise click.BadParameter(str(error), param_hint="'--policy'") from None
        _check_joints(_policy_name(path), policies[-1], setup)
    check_setup_step(setup, dt)
    chosen = _evaluation_certificate([_policy_name(path) for path in policy_files], policies,
                                     certificate)
    config = evaluation_config(chosen, setup, delay, duration, dt)
    chosen = config.safety_certificate()  # extended to the setup's other plants
    check_covers_setup(chosen, config.setup, delay, *_evaluation_advice(certificate))
    click.echo(f"evaluating under {chosen.gain_variation} on the certified set of the box "
               + _box_text(chosen), err=True)

    def searching() -> None:
        click.echo(f"finding the comparators of {chosen.gain_variation} for setup "
                   f"{config.setup.fingerprint} (best static gains, and for a class with "
                   "switching the semi-active law and the open-loop schedule; a few minutes) "
                   "...", err=True)

    policies, comparators = as_run(policies, chosen, config, on_search=searching,
                                   fall_back=fall_back)
    asides = [f"{_policy_name(path)} {text}"
              for path, policy in zip(policy_files, policies, strict=True)
              if (text := stepped_aside(policy)) is not None]
    for text in asides:
        click.echo(text, err=True)
    per_scenario = compare(policies, scenarios, seed, chosen, delay, duration, comparators,
                           setup=setup, dt=dt, fall_back=False)  # as_run decided already
    rows = tuner_rows(policies, chosen.gain_variation)
    tuner = next(iter(rows))
    delays = delay or ", ".join(dict.fromkeys(config.setup.network.forward.profiles
                                              + config.setup.network.backward.profiles))
    preamble = report_preamble(comparators, scenarios, seed, delays, tuner, len(rows[tuner]),
                               duration, others=_other_tuners(rows, tuner), setup=config.setup)
    preamble += "".join(f"\n{text}.\n" for text in asides)
    summary = save_report(per_scenario, out, baseline=REFERENCE, preamble=preamble, tuner=tuner,
                          schedule=schedule_label(chosen.gain_variation))
    click.echo(to_markdown(summary, baseline=REFERENCE), nl=False)
    unsafe = int(summary["unsafe_actions"].sum())
    click.echo(f"report in {out}; unsafe actions: {unsafe}")
    return 0 if unsafe == 0 else 1


def _evaluation_advice(certificate: Path | None) -> tuple[str, str]:
    """The certificate evaluate runs under in words, and what to do when the network exceeds it."""
    if certificate is not None:
        return ("the --certificate", "give a --setup or --delay that stays within it, or a "
                                     "--certificate for these delays")
    return ("the policy's certificate", "give a --setup or --delay that stays within it, or a "
                                        "policy trained for this network")


def _policy_name(path: Path) -> str:
    """A policy as the user names it: a shipped policy's name, else its path."""
    from teleopkit.rl.policy import SHIPPED_POLICIES, resolve_policy

    return next((name for name in SHIPPED_POLICIES if resolve_policy(name) == path), str(path))


def _check_joints(name: str, policy: GainPolicy, setup: Setup) -> None:
    """Refuse, in one line, a policy that tunes another number of joints than the setup's."""
    joints = policy.low.size // 2
    if joints != setup.n_joints:
        raise click.BadParameter(
            f"{name} tunes the gains of {joints} joints, the setup's arms have "
            f"{setup.n_joints}: search a gain law (teleopkit search-law --setup FILE) or train "
            "a tuner (teleopkit train --setup FILE) for them", param_hint="'--policy'")


def _evaluation_certificate(names: list[str], policies: list[GainPolicy],
                            certificate: Path | None) -> GainCertificate:
    """The one certificate every policy runs under: the file given, else the first policy's.

    A policy whose class it does not cover is refused in one line that names the conflict:
    the file given, or the two policies (by ``names``) and their classes, and what would do.
    """
    from teleopkit.rl.comparison import check_covers, policy_certificate

    chosen = (read_certificate(certificate) if certificate is not None
              else policy_certificate(policies[0]))
    if certificate is None:
        for name, policy in zip(names[1:], policies[1:], strict=True):
            _refuse_other_class(names[0], chosen, name, policy_certificate(policy))
    try:
        for policy in policies:
            check_covers(chosen, policy)
    except ValueError as error:
        hint = "--certificate" if certificate is not None else "--policy"
        raise click.BadParameter(str(error), param_hint=f"'{hint}'") from None
    return chosen


def _refuse_other_class(first: str, chosen: GainCertificate, name: str,
                        trained: GainCertificate) -> None:
    """Refuse a policy of a class the first policy's certificate does not cover, naming both."""
    if chosen.variation.covers(trained.variation):
        return
    way = (f"its class does not cover {trained.gain_variation}, which covers both: give "
           f"--policy {name} first, or a --certificate of that class"
           if trained.variation.covers(chosen.variation) else
           "neither class covers the other, so evaluate them in separate runs")
    raise click.BadParameter(
        f"{first} was trained under {chosen.gain_variation} and {name} under "
        f"{trained.gain_variation}, and every policy runs under one certificate (the first "
        f"one's): {way}", param_hint="'--policy'")


def _other_tuners(rows: dict[str, list[GainPolicy]], tuner: str) -> dict[str, str]:
    """A sentence for each tuner's row after the first one's (the report's preamble)."""
    from teleopkit.rl.comparison import policy_observation

    return {name: (f"another tuner given with --policy ({len(group)} "
                   f"polic{'y' if len(group) == 1 else 'ies'}), run under the same certificate "
                   f"with its own observation ({policy_observation(group[0])}); the comparators "
                   f"were searched for `{tuner}`.")
            for name, group in rows.items() if name != tuner}


@click.command("reproduce")
@click.option("--out", type=click.Path(path_type=Path), default="runs/reproduce",
              show_default=True, help="Directory for the figures (PNG) and the comparison table.")
@click.option("--scenarios", type=click.IntRange(min=1), default=32, show_default=True,
              help="Held-out scenarios of the comparison table.")
@setup_option
def reproduce_command(out: Path, scenarios: int, setup: Setup) -> int:
    """Paper figures and comparison table from the shipped pretrained policies (no training).

    With --setup, the scenarios are drawn from that setup (another operator, start or network
    of the paper's plant; the shipped tuners are certified for the paper's plant only) and
    every comparator is searched for it.

    The table leads with the shipped tuner whose certificate covers what it does with the
    gains, beside the best static gains of the frozen class (the reference), its own class's
    best static gains, a tuned semi-active damping law and its open-loop mean schedule; the
    paper's tuner, trained under the frozen-gain certificate, which does not cover its
    switching, is the row "TD3 (paper, frozen)" (covered: no).
    """
    from teleopkit.rl.comparison import REFERENCE
    from teleopkit.rl.evaluation import to_markdown
    from teleopkit.rl.reproduction import reproduce

    check_output_dir(out, "--out")
    result = reproduce(out, scenarios, setup=setup)
    click.echo(to_markdown(result.summary, baseline=REFERENCE), nl=False)
    unsafe = int(result.summary["unsafe_actions"].sum())
    click.echo(f"wrote {len(result.figures)} figures and the table to {out}; unsafe actions: "
               f"{unsafe}")
    return 0 if unsafe == 0 else 1
