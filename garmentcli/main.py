"""Entry point of the `garment` command: the click group and its subcommands."""

from __future__ import annotations

import logging

import click

from garmentcli import (
    attribute,
    bake,
    dataset,
    examples,
    fit,
    make_body,
    metrics,
    preprocess,
    render,
    tradeoff,
    unpose,
)
from garmentcli import train as train_cmd


class _Group(click.Group):
    """click.Group whose commands' file-system errors on a named path (a name longer than the file system takes,
    a device that fails to read) end as one line naming the path, not a traceback."""

    def invoke(self, ctx):
        try:
            return super().invoke(ctx)
        except OSError as exc:
            if exc.filename is None or isinstance(exc, click.ClickException):
                raise
            name = str(exc.filename)
            shown = name if len(name) <= 80 else f"{name[:40]}...{name[-20:]} ({len(name)} characters)"
            raise click.ClickException(f"'{shown}': {exc.strerror or exc}") from None


@click.group(cls=_Group, context_settings={"help_option_names": ["-h", "--help"]})
@click.option("-v", "--verbose", is_flag=True, help="Log more detail to stderr.")
@click.version_option(package_name="garment")
def cli(verbose: bool) -> None:
    """Bake garment animation on SMPL-format bodies and measure it."""
    logging.basicConfig(level=logging.INFO if verbose else logging.WARNING,
                        format="garment: %(levelname)s: %(message)s")


cli.add_command(bake.bake)
cli.add_command(dataset.dataset)
cli.add_command(metrics.metrics)
cli.add_command(render.render)
cli.add_command(examples.examples)
cli.add_command(make_body.make_body)
cli.add_command(preprocess.preprocess)
cli.add_command(train_cmd.train)
cli.add_command(attribute.attribute)
cli.add_command(tradeoff.tradeoff)
cli.add_command(unpose.unpose)
cli.add_command(fit.fit)


if __name__ == "__main__":  # python -m garmentcli.main ...
    cli()
