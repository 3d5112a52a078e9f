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


@click.group(context_settings={"help_option_names": ["-h", "--help"]})
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
