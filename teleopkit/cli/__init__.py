"""The ``teleopkit`` command line.

Exit codes: 0 success (or certified), 1 ran but the answer is negative (not certified, unsafe
actions, a falsification finding, a simulated run that diverged) or the model failed (a run
left the state bound: one line),
2 bad input with a one-line message on standard error and no
traceback, 130 interrupted (Ctrl-C), with one line. Each subcommand imports what it needs when it
runs, so ``teleopkit --help`` starts at once; :mod:`~teleopkit.cli.options` holds what they share.
"""

from __future__ import annotations

from collections.abc import Sequence

import click

from teleopkit.cli.certificates import certify
from teleopkit.cli.laws import search_law_command
from teleopkit.cli.robustness import campaign_command, falsify_command
from teleopkit.cli.setup import setup_command
from teleopkit.cli.simulate import simulate_command
from teleopkit.cli.tuning import evaluate_command, reproduce_command, train_command
from teleopkit.files import RunLocked

__all__ = ["cli", "main"]


@click.group(context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(package_name="teleopkit")
def cli() -> None:
    """Delayed bilateral teleoperation: simulate, certify, train and evaluate gain tuners."""


for _command in (setup_command, simulate_command, certify, train_command, search_law_command,
                 evaluate_command, reproduce_command, campaign_command, falsify_command):
    cli.add_command(_command)


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line and return its exit code (bad input: 2, one line, no traceback).

    Parameters
    ----------
    argv : sequence of str, optional
        Arguments; ``sys.argv[1:]`` by default.

    Returns
    -------
    int
        The exit code.
    """
    try:
        result = cli.main(args=list(argv) if argv is not None else None, prog_name="teleopkit",
                          standalone_mode=False)
    except click.exceptions.Exit as done:
        return int(done.exit_code)
    except click.ClickException as error:
        click.echo(f"teleopkit: error: {error.format_message()}", err=True)
        return 2
    except (ValueError, OSError, ImportError, RunLocked) as error:
        return _one_line(error, 2)
    except (click.exceptions.Abort, KeyboardInterrupt):
        click.echo("teleopkit: interrupted (finished rounds, chunks and proven sets are kept)",
                   err=True)
        return 130
    except RuntimeError as error:  # after Abort (one too): the model failed, never expected
        return _one_line(error, 1)
    return int(result) if isinstance(result, int) else 0


def _one_line(error: Exception, code: int) -> int:
    """Say ``error`` in one line on standard error; return the exit code."""
    message = str(error).splitlines()[0] if str(error) else type(error).__name__
    click.echo(f"teleopkit: error: {message}", err=True)
    return code
