"""What the commands share: option parsers and the checks made before anything runs.

Every check raises :class:`click.BadParameter` naming the option and the value, so the command
line prints one line (``Invalid value for '--out': ...``) and exits with 2. Outputs are checked
before a run starts, so a bad path never leaves half the results behind.
"""

from __future__ import annotations

import math
import os
import shutil
import tempfile
from contextlib import AbstractContextManager
from pathlib import Path
from typing import TYPE_CHECKING, Any

import click

from teleopkit.progress import show_progress

if TYPE_CHECKING:
    from teleopkit.certification.gain_certificate import GainCertificate
    from teleopkit.certification.gain_classes import GainVariation
    from teleopkit.setup import Setup

__all__ = ["DELAY_SPECS", "IMAGE_SUFFIXES", "FiniteFloat", "certificate_option",
           "check_covers_setup", "check_disk", "check_output", "check_output_dir", "check_traces",
           "delay_spec", "gain_variation", "gains", "load_setup", "progress", "read_certificate",
           "read_setup", "require_torch", "run_duration", "setup_option", "single_thread"]

IMAGE_SUFFIXES = (".png", ".pdf", ".svg", ".jpg", ".jpeg", ".tif", ".tiff", ".eps", ".webp")
"""Figure formats the plots can be written in (matplotlib's, by suffix)."""

DELAY_SPECS = ("paper | constant:T | sine:MEAN:AMP:FREQ (FREQ in Hz; the backward channel's "
               "phase shifted by a quarter period) | switching:LOW:HIGH:DWELL (each DWELL at "
               "LOW or HIGH, the two channels drawn independently) | csv:PATH (the same trace "
               "on both channels); times in seconds unless written with a unit (500ms)")
"""What ``--delay`` takes (:func:`~teleopkit.delays.spec.parse_delay`), for the options' help."""


def _bad(option: str, message: str) -> click.BadParameter:
    return click.BadParameter(message, param_hint=f"'{option}'")


class FiniteFloat(click.FloatRange):
    """A :class:`click.FloatRange` that refuses NaN and infinities, which a range lets through.

    Parameters
    ----------
    min, max : float, optional
        The bounds, as for :class:`click.FloatRange`.
    min_open, max_open : bool
        Whether a bound is excluded.
    """

    def convert(self, value: Any, param: click.Parameter | None,
                ctx: click.Context | None) -> Any:
        """The number, refused in one line when it is not finite or not in the range.

        Parameters
        ----------
        value : object
            The text given (or a default number).
        param : click.Parameter or None
            The option, for the message.
        ctx : click.Context or None
            Click's context.

        Returns
        -------
        float
            The number.
        """
        number = click.FLOAT.convert(value, param, ctx)
        if not math.isfinite(number):
            self.fail(f"{value} is not a finite number", param, ctx)
        return super().convert(number, param, ctx)


def run_duration(ctx: click.Context | None, param: click.Parameter | None, value: float) -> float:
    """Option callback of ``--duration``: seconds, a whole number of control periods.

    Parameters
    ----------
    ctx : click.Context or None
        Unused.
    param : click.Parameter or None
        Unused (the option is ``--duration``).
    value : float
        The seconds given.

    Returns
    -------
    float
        ``value``, refused (one line) unless positive, finite and a whole number of the
        10 ms control periods every run holds its gains over
        (:func:`~teleopkit.sim.timing.periods`).
    """
    from teleopkit.sim.timing import CONTROL_PERIOD, periods

    try:
        periods(value, CONTROL_PERIOD)
    except ValueError as error:
        raise _bad("--duration", str(error)) from None
    return value


def gains(ctx: click.Context | None, param: click.Parameter | None, value: str) -> list[float]:
    """Option callback: ``K`` (every joint) or ``K1,K2,...`` (one per joint), non-negative.

    Parameters
    ----------
    ctx : click.Context or None
        Unused.
    param : click.Parameter or None
        The option (for the message).
    value : str
        The text given.

    Returns
    -------
    list of float
        The numbers (the command checks their count against the setup's joints).
    """
    name = f"--{param.name}" if param is not None and param.name else "gain"
    try:
        numbers = [float(x) for x in value.split(",")]
    except ValueError:
        raise _bad(name, f"needs a number or two separated by a comma, got {value!r}") from None
    if not all(math.isfinite(v) and v >= 0 for v in numbers):
        raise _bad(name, f"must be finite and non-negative, got {value!r}")
    return numbers


def gain_variation(ctx: click.Context | None, param: click.Parameter | None,
                   value: str | None) -> GainVariation | None:
    """Option callback: a gain class (:func:`~teleopkit.certification.parse_gain_variation`).

    Parameters
    ----------
    ctx : click.Context or None
        Unused.
    param : click.Parameter or None
        The option.
    value : str
        The class as text.

    Returns
    -------
    GainVariation or None
        The class (None when the option was not given and has no default).
    """
    from teleopkit.certification.gain_classes import parse_gain_variation

    if value is None:
        return None
    try:
        return parse_gain_variation(value)
    except ValueError as error:
        raise _bad("--gain-variation", str(error)) from None


def delay_spec(ctx: click.Context | None, param: click.Parameter | None,
               value: str | None) -> str | None:
    """Option callback: a delay spec that :func:`~teleopkit.delays.parse_delay` reads.

    Parameters
    ----------
    ctx : click.Context or None
        Unused.
    param : click.Parameter or None
        The option.
    value : str, optional
        The spec (None: the setup's network).

    Returns
    -------
    str or None
        The spec, checked (traces are read once here).
    """
    from teleopkit.delays.spec import parse_delay

    if value is None:
        return None
    try:
        parse_delay(value)
    except ValueError as error:
        raise _bad("--delay", str(error)) from None
    return value


_CERTIFY = ("certify for the setup's delays (teleopkit certify --setup FILE --json) or give a "
            "--setup whose network stays within them")
"""What to do about a certificate file whose delay bounds the setup's network exceeds."""


def check_traces(setup: Setup, duration: float, option: str) -> None:
    """Refuse, before any work, a recorded delay trace that ends before the runs do.

    Parameters
    ----------
    setup : Setup
        The setup, its network replaced by a ``--delay`` if one was given
        (:meth:`~teleopkit.setup.Setup.with_delay`):
        :meth:`~teleopkit.setup.network.Network.check_ends`.
    duration : float
        The longest run in seconds.
    option : str
        The option that gave the network, for the message.
    """
    try:
        setup.network.check_ends(duration)
    except ValueError as error:
        raise _bad(option, str(error)) from None


def check_setup_step(setup: Setup, dt: float) -> None:
    """Refuse, before any work, a step that cannot integrate one of the setup's plants.

    :func:`teleopkit.sim.stability.check_step` on every plant of the setup and, for a plant
    given as ranges, on the ranges' ends; the message names a step that does.

    Parameters
    ----------
    setup : Setup
        The setup.
    dt : float
        The integration step in seconds (``--dt``).
    """
    from teleopkit.sim import stability
    from teleopkit.sim.timing import CONTROL_PERIOD

    ends = (end for plant, ranges in zip(setup.plants, setup.ranges, strict=True) if ranges
            for end in ranges.corners(plant))
    for plant in (*setup.plants, *ends):
        try:
            stability.check_step(plant, dt, CONTROL_PERIOD)
        except ValueError as error:
            raise _bad("--dt", str(error)) from None


def check_covers_setup(certificate: GainCertificate, setup: Setup, delay: str | None,
                       whose: str, advice: str = _CERTIFY) -> None:
    """Refuse a certificate for another plant or for delays the setup's network can exceed.

    :meth:`~teleopkit.certification.gain_certificate.GainCertificate.check`, with its hint on
    units only for a ``--delay`` number typed without one that looks like milliseconds.

    Parameters
    ----------
    certificate : GainCertificate
        The certificate.
    setup : Setup
        The setup, its network replaced by ``delay`` if given.
    delay : str, optional
        The ``--delay`` typed (None: the setup's own network).
    whose : str
        The certificate in words, such as ``"the policy's certificate"`` (a refusal of the
        setup's network starts with it).
    advice : str
        What to do when the setup's network reaches beyond the certificate's delay bounds
        (by default: certify for them, or another setup).
    """
    from teleopkit.certification.gain_certificate import DelayBoundError

    network = setup.network
    try:
        certificate.check(setup.plants, *network.reached_bounds, network.reached_floors,
                          units_hint=_typed_in_ms(delay))
    except DelayBoundError as error:
        if delay is not None:
            raise _bad("--delay", str(error)) from None
        raise ValueError(f"{whose} covers {error.direction} delays up to {error.bound:g} s and "
                         f"the setup's network reaches {error.reach:.6g} s: {advice}") from None


def _typed_in_ms(delay: str | None) -> bool:
    """Whether a typed delay spec holds a delay without a unit above 1 (seconds: meant as ms?)."""
    kind, _, rest = (delay or "").partition(":")
    delays = rest.split(":")[:{"constant": 1, "sine": 2, "switching": 2}.get(kind, 0)]
    return any(_bare_above_one(value) for value in delays)


def _bare_above_one(text: str) -> bool:
    """Whether ``text`` is a plain number (no unit) above 1."""
    try:
        return float(text) > 1
    except ValueError:
        return False


def _probe(directory: Path) -> str | None:
    """Why a file cannot be created in ``directory`` (the OS's words), or None if it can."""
    try:
        handle, name = tempfile.mkstemp(prefix=".teleopkit-probe-", dir=directory)
    except OSError as error:
        return error.strerror or str(error)
    os.close(handle)
    os.unlink(name)
    return None


def check_output(path: Path, option: str, suffixes: tuple[str, ...] | None = None) -> Path:
    """Refuse an output file that cannot be written, before anything runs.

    A file is created in its directory and removed again: the message is the operating
    system's own reason (a read-only or pseudo file system says so).

    Parameters
    ----------
    path : Path
        The file.
    option : str
        Its option, for the message.
    suffixes : tuple of str, optional
        Accepted suffixes (lower case, with the dot).

    Returns
    -------
    Path
        ``path``.
    """
    if suffixes is not None and path.suffix.lower() not in suffixes:
        raise _bad(option, f"needs a file name ending in {', '.join(suffixes)}, got "
                           f"{path.name!r}")
    if path.is_dir():
        raise _bad(option, f"{path} is a directory, not a file")
    parent = path.parent if str(path.parent) else Path(".")
    if not parent.is_dir():
        raise _bad(option, f"directory {parent} does not exist")
    reason = _probe(parent)
    if reason is None and path.exists() and not os.access(path, os.W_OK):
        reason = "Permission denied"
    if reason is not None:
        raise _bad(option, f"cannot write {path}: {reason}")
    return path


def check_output_dir(path: Path, option: str) -> Path:
    """Refuse an output directory that cannot be created or written, before anything runs.

    Parameters
    ----------
    path : Path
        The directory (created later, with its parents, if needed).
    option : str
        Its option, for the message.

    Returns
    -------
    Path
        ``path``.
    """
    if path.exists() and not path.is_dir():
        raise _bad(option, f"{path} is a file, not a directory")
    existing = path
    while not existing.exists():
        existing = existing.parent
    if not existing.is_dir():
        raise _bad(option, f"{existing} is not a directory")
    reason = _probe(existing)
    if reason is not None:
        raise _bad(option, f"cannot write in {existing}: {reason}")
    return path


def check_disk(path: Path, size: int, option: str) -> None:
    """Refuse an output that would not fit on its disk.

    Parameters
    ----------
    path : Path
        The file (its directory must exist).
    size : int
        Estimated size in bytes.
    option : str
        Its option, for the message.
    """
    free = shutil.disk_usage(path.parent if str(path.parent) else ".").free
    if size > free:
        raise _bad(option, f"the output would take about {size / 1e9:.3g} GB, more than the "
                           f"{free / 1e9:.3g} GB free on its disk")


def read_certificate(path: Path) -> GainCertificate:
    """Read a certificate file and re-check it: nothing unverified reaches the plant.

    Parameters
    ----------
    path : Path
        JSON written by ``teleopkit certify --json``.

    Returns
    -------
    GainCertificate
        The certificate, verified.
    """
    from teleopkit.certification.verification import load_certificate

    try:
        text = path.read_text()
    except (OSError, UnicodeDecodeError) as error:
        reason = getattr(error, "strerror", None) or str(error)
        raise _bad("--certificate", f"cannot read {path}: {reason}") from None
    try:
        return load_certificate(text)
    except ValueError as error:
        raise _bad("--certificate", f"{path}: {error}") from None


def certificate_option(function: Any) -> Any:
    """The ``--certificate FILE`` option of the commands that run a safety layer.

    Parameters
    ----------
    function : callable
        The click command (or already decorated function) to add the option to.

    Returns
    -------
    callable
        ``function`` with the option attached.
    """
    return click.option(
        "--certificate", type=click.Path(dir_okay=False, path_type=Path), default=None,
        help="Gain certificate (the JSON of teleopkit certify --json) whose set the safety "
             "layer projects onto; it must be for this plant and these delays [default: the "
             "closed form on K_r in [1, 50], B_r in [1, 150] for the delays the setup's "
             "network reaches].")(function)


def read_setup(ctx: click.Context | None, param: click.Parameter | None,
               value: Path | None) -> Setup:
    """Option callback of ``--setup FILE|NAME``: the setup it describes, the paper's by default.

    Parameters
    ----------
    ctx, param
        Click's context and parameter (unused).
    value : Path, optional
        A setup file (YAML or JSON), or the name of a shipped setup
        (:data:`~teleopkit.setup.SHIPPED_SETUPS`; write ``./mixed`` for a file called
        ``mixed``).

    Returns
    -------
    Setup
        The setup; an unreadable or malformed file is one line naming the key path.
    """
    return load_setup(value, "--setup")


def load_setup(value: Path | None, option: str) -> Setup:
    """The setup a file or a shipped setup's name describes, the paper's for None.

    Parameters
    ----------
    value : Path, optional
        A setup file (YAML or JSON), or the name of a shipped setup.
    option : str
        The option or argument that gave it (``--setup``, ``FILE``), for the message.

    Returns
    -------
    Setup
        The setup; an unreadable or malformed file is one line naming ``option`` and the key
        path.
    """
    from teleopkit.setup import SHIPPED_SETUPS, Setup, SetupError, shipped_setup_path

    if value is None:
        return Setup.paper()
    if str(value) in SHIPPED_SETUPS:
        value = shipped_setup_path(str(value))
    elif not Path(value).exists() and Path(value).name == str(value) and not Path(value).suffix:
        raise _bad(option, f"{value} is neither a setup file nor a shipped setup "
                           f"({', '.join(SHIPPED_SETUPS)})")
    try:
        return Setup.from_file(value)
    except SetupError as error:
        raise _bad(option, str(error)) from None


def dt_option(function: Any) -> Any:
    """The ``--dt`` option of the commands that simulate (the integration step).

    Parameters
    ----------
    function : callable
        The click command (or already decorated function) to add the option to.

    Returns
    -------
    callable
        ``function`` with the option attached (its value the step in seconds).
    """
    from teleopkit.sim.timing import DEFAULT_DT

    return click.option(
        "--dt", type=FiniteFloat(min=0, min_open=True), default=DEFAULT_DT, show_default=True,
        help="Integration step [s], dividing the 10 ms control period; the default is within "
             "2e-6 rad of a converged run at the paper's gains, 1.4e-5 at the least damped "
             "certified gains (0.00125: 4e-7). A plant whose springs or dampers it cannot "
             "integrate (light links, stiff joints or walls) is refused naming a step that "
             "does.")(function)


def setup_option(function: Any) -> Any:
    """The ``--setup FILE`` option every command takes.

    Parameters
    ----------
    function : callable
        The click command (or already decorated function) to add the option to.

    Returns
    -------
    callable
        ``function`` with the option attached (its value a :class:`~teleopkit.setup.Setup`).
    """
    return click.option(
        "--setup", "setup", type=click.Path(dir_okay=False, path_type=Path), default=None,
        callback=read_setup,
        metavar="FILE|NAME",
        help="Setup file (YAML: plant, network, operator, start; see teleopkit setup), or a "
             "shipped setup: paper, mixed (a training distribution around the paper's) "
             "[default: paper].")(function)


def require_torch() -> None:
    """Refuse, in one line, a command that trains when PyTorch is not installed.

    Evaluating and reproducing run numpy policies; training is the extra ``teleopkit[train]``.
    """
    import importlib.util

    if importlib.util.find_spec("torch") is None:
        raise click.ClickException("training needs PyTorch, an optional dependency: "
                                   "pip install 'teleopkit[train]'")


def single_thread() -> None:
    """One torch thread: the second core belongs to the simulator or to other work."""
    import torch

    torch.set_num_threads(1)


def progress(enabled: bool) -> AbstractContextManager[None]:
    """Show the library's progress (:mod:`teleopkit.progress`) while a command runs.

    Parameters
    ----------
    enabled : bool
        Whether to show it (``--progress``): on a terminal only, redirected output stays clean.

    Returns
    -------
    contextlib.AbstractContextManager
        The block that shows it.
    """
    return show_progress(None if enabled else False)
