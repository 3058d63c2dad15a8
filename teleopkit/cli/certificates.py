"""``teleopkit certify``: is every gain of a box stable for the delay bounds, and in which class."""

from __future__ import annotations

import json
from dataclasses import replace
from typing import TYPE_CHECKING

import click

from teleopkit.cli.options import FiniteFloat, gain_variation, progress, setup_option
from teleopkit.setup.reading import listed

if TYPE_CHECKING:
    from teleopkit.certification.gain_certificate import GainCertificate
    from teleopkit.model.params import TeleoperatorParams
    from teleopkit.setup import Setup
    from teleopkit.setup.network import Channel

__all__ = ["certify"]

_BOUND = FiniteFloat(min=0, min_open=True, max=1e6)
_FLOOR = FiniteFloat(min=0, max=1e6)


@click.command()
@click.option("--kr", "kr_range", required=True, help="Range of K_r, MIN:MAX (every joint).")
@click.option("--br", "br_range", required=True, help="Range of B_r, MIN:MAX (every joint).")
@click.option("--kl", type=FiniteFloat(min=0, min_open=True), default=None,
              help="Local gain K_l of every joint [default: the setup's].")
@click.option("--bl", type=FiniteFloat(min=0, min_open=True), default=None,
              help="Local damping B_l of every joint [default: the setup's].")
@click.option("--tl-max", type=_BOUND, default=None,
              help="Forward delay bound T_l* [s] [default: the setup's network.forward.max, "
                   "1 s for the paper].")
@click.option("--tr-max", type=_BOUND, default=None,
              help="Backward delay bound T_r* [s] [default: the setup's network.backward.max].")
@click.option("--tl-min", type=_FLOOR, default=None,
              help="Minimum forward delay T_l_min [s] (a network's latency floor; used by the "
                   "LMIs, the closed form covers delays from 0) [default: the setup's "
                   "network.forward.min].")
@click.option("--tr-min", type=_FLOOR, default=None,
              help="Minimum backward delay T_r_min [s] [default: the setup's "
                   "network.backward.min].")
@click.option("--method", type=click.Choice(["nuno", "lmi", "all"]), default="nuno",
              show_default=True,
              help="nuno: closed form and its storage (instant); lmi: LK/LMI on the "
                   "linearisation (seconds per joint box, minutes for two joints); all: every "
                   "method that covers the class, the best answer first.")
@click.option("--gain-variation", "variation", default="frozen", show_default=True,
              callback=gain_variation,
              help="frozen | switching | rate:R | scheduled:L | tank[:T0 or :Drad] (R in gain "
                   "units per second, L a log budget per episode, T0 an initial tank level in "
                   "rad^2, D the spring deflection in rad the tank's bound allows, e.g. "
                   "tank:0.5rad; tank alone starts empty).")
@click.option("--json", "as_json", is_flag=True, help="Print the certificate as JSON.")
@click.option("--cache/--no-cache", default=True, show_default=True,
              help="Reuse an LMI certificate of the same question from $TELEOPKIT_CACHE (else "
                   "~/.cache/teleopkit), re-verified against the plant; store new ones there.")
@click.option("--progress/--no-progress", "show_progress", default=True, show_default=True,
              help="Show the LMI search (cells solved, margin bracket) on a terminal.")
@click.option("--workers", type=click.IntRange(min=1), default=None,
              help="Worker processes of the LMI solves (1: in this process) [default: "
                   "$TELEOPKIT_WORKERS, else the core count].")
@setup_option
def certify(kr_range: str, br_range: str, kl: float | None, bl: float | None,
            tl_max: float | None, tr_max: float | None, tl_min: float | None,
            tr_min: float | None, method: str, variation: object, as_json: bool, cache: bool,
            show_progress: bool, workers: int | None, setup: Setup) -> int:
    """Certify that every remote gain in the ranges is stable for the delay bounds.

    It answers for the setup's plant (the paper's by default; a setup's several plants
    together, by the closed form) and names it. The answer says
    what it covers: the gain class in plain words and every assumption (see the
    documentation's "What is certified" page).
    """
    from teleopkit.certification import best_certificate, certify_all, methods_for
    from teleopkit.certification.gain_sets import GainBox, parse_range
    from teleopkit.certification.nuno.scheduled import plants_tank
    from teleopkit.certification.report import certificate_table
    from teleopkit.model.params import PDGains

    tl_min, tl_max = _delay_range("l", tl_min, tl_max, setup.network.forward)
    tr_min, tr_max = _delay_range("r", tr_min, tr_max, setup.network.backward)
    n = setup.n_joints
    plants = [replace(plant, local_gains=PDGains(
        plant.local_gains.stiffness if kl is None else (kl,) * n,
        plant.local_gains.damping if bl is None else (bl,) * n)) for plant in setup.plants]
    params = plants[0]
    if (len(plants) > 1 or setup.plant_ranges) and method != "nuno":
        what = f"{len(plants)} plants" if len(plants) > 1 else "a plant with ranges"
        raise click.BadParameter(f"the setup has {what}: the closed form (nuno) certifies them "
                                 "together, an LMI certificate is one plant's",
                                 param_hint="'--method'")
    box = GainBox.uniform(parse_range(kr_range, "--kr"), parse_range(br_range, "--br"), n)
    # a tank asked in rad is sized for every plant, range and start of the setup
    variation = plants_tank(plants, box, tl_max, tr_max, variation, setup.ranges, setup.start)
    proven: list[GainCertificate] = []

    def improved(certificate: GainCertificate) -> None:
        proven.append(certificate)
        if not as_json:
            click.echo(f"LMI: proven so far for {certificate.gain_variation} gains at the "
                       f"delay bounds: {_set_text(certificate)} (searching further)")

    def solve() -> list[GainCertificate]:
        with progress(show_progress):
            found = certify_all(params, box, tl_max, tr_max, method, variation, tl_min, tr_min,
                                workers=workers, cache=cache, on_proven=improved)
        return _covering(found, plants, setup)

    # the closed form alone is instant: its answer (or a refusal) comes before anything printed
    results = solve() if method == "nuno" else None
    if not as_json:
        click.echo(_plant_line(plants, setup))
    if "lmi" in methods_for(method, variation) and not as_json:
        click.echo("closed form (instant; the LMI answer follows):")
        closed = certify_all(params, box, tl_max, tr_max, "nuno", variation)
        click.echo(_indented(certificate_table(closed, footer=False, start=setup.start)))
    try:
        results = results if results is not None else solve()
    except KeyboardInterrupt:
        if proven:
            _answer([proven[-1]], as_json, setup,
                    "interrupted: the best set proven so far (its delay margin was not searched)")
        raise
    best = best_certificate(results)
    _answer(results, as_json, setup)
    return 0 if best.certified else 1


def _plant_line(plants: list[TeleoperatorParams], setup: Setup) -> str:
    """The line naming the plant certified (and that the others are, with it)."""
    from teleopkit.certification.report import plant_text

    others = f" (and {len(plants) - 1} other plants, certified with it)" if len(plants) > 1 else ""
    others += " (and every plant of its ranges)" if setup.plant_ranges else ""
    return f"plant: {plant_text(plants[0])}{others}"


def _covering(results: list[GainCertificate], plants: list[TeleoperatorParams],
              setup: Setup) -> list[GainCertificate]:
    """The certificates extended to every plant of the setup (the closed form's, one set).

    Refused in one line where the closed form certifies another set for one of the plants,
    naming it and what to do instead.
    """
    from teleopkit.certification.verification import cover_plants

    try:
        return [cover_plants(result, plants, setup.ranges) for result in results]
    except ValueError:
        raise click.BadParameter(
            f"the closed form certifies another set for {_differing(plants)} than for plant 1, "
            "so no one certificate covers the plants: write a setup file per plant (its plant "
            "entry alone) and certify each", param_hint="'--setup'") from None


def _differing(plants: list[TeleoperatorParams]) -> str:
    """The first plant whose local gains differ from the first plant's, and how, in words."""
    first = plants[0].local_gains
    for k, plant in enumerate(plants[1:], start=2):
        changes = [f"{name} {listed(new)} against {listed(old)}" for name, new, old in
                   (("K_l", plant.local_gains.stiffness, first.stiffness),
                    ("B_l", plant.local_gains.damping, first.damping)) if new != old]
        if changes:
            return f"plant {k} (its local gains {', '.join(changes)})"
    return "one of the plants"


def _delay_range(side: str, low: float | None, high: float | None,
                 channel: Channel) -> tuple[float, float]:
    """A direction's minimum delay and bound, the setup's where not given; refused unless below.

    The message blames the option given (``--t{side}-min`` first), or the setup when neither was.
    """
    floor = channel.min if low is None else low
    bound = channel.max if high is None else high
    if not floor < bound:
        option = (f"--t{side}-min" if low is not None else f"--t{side}-max" if high is not None
                  else "--setup")
        raise click.BadParameter(f"the minimum delay T_{side}_min = {floor:g} s is not below the "
                                 f"bound T_{side}* = {bound:g} s", param_hint=f"'{option}'")
    return floor, bound


def _indented(text: str) -> str:
    return "\n".join(f"  {line}" if line else line for line in text.splitlines())


def _set_text(certificate: GainCertificate) -> str:
    """The proven set in a few words: the whole box, or the polygon of each joint."""
    if certificate.certified:
        return "the whole box"
    return "; ".join(f"joint {i + 1} " + " ".join(
        f"({k:.4g}, {b:.4g})" for k, b in certificate.polytope.joint_vertices(i))
        for i in range(certificate.box.n_joints))


def _answer(results: list[GainCertificate], as_json: bool, setup: Setup, note: str = "") -> None:
    """Print the answer: the table (with ``note`` first), or the best certificate as JSON.

    The JSON records the setup it was asked for (``setup``) beside the certified plant.
    """
    from teleopkit.certification import best_certificate
    from teleopkit.certification.report import certificate_table

    best = best_certificate(results)
    if as_json:
        payload = best.to_dict()
        guarantee = best.guarantee(setup.start)  # from every start of the setup
        if guarantee is not None:
            payload["guarantee"] = {**guarantee.to_dict(), "start": setup.start.to_data()}
        payload["results"] = [c.to_dict() for c in results]
        payload["setup"] = setup.record
        if note:
            payload["interrupted"] = note
        click.echo(json.dumps(payload, indent=2))
    else:
        click.echo((f"{note}\n" if note else "") + certificate_table(results, start=setup.start))
