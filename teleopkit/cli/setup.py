"""``teleopkit setup``: print the paper's setup file, or check one and say what it describes."""

from __future__ import annotations

from pathlib import Path

import click

from teleopkit.cli.options import load_setup

__all__ = ["setup_command"]


@click.command("setup")
@click.argument("file", required=False, type=click.Path(dir_okay=False, path_type=Path))
def setup_command(file: Path | None) -> None:
    """Print the paper's setup file, or check FILE and say what it describes.

    A setup file (YAML or JSON) describes the plant, the network, the operator and the start;
    every command takes one with --setup FILE. Start from the paper's:
    teleopkit setup > my_setup.yaml.
    """
    from teleopkit.setup import paper_setup_path

    if file is None:
        click.echo(paper_setup_path().read_text(encoding="utf-8"), nl=False)
        return
    setup = load_setup(file, "FILE")
    click.echo(f"{file} describes:")
    for line in setup.describe():
        click.echo(f"  {line}")
