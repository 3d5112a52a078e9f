"""placeholder"""
import click


@click.command(name="make-body")
def make_body():
    """Not yet implemented."""
