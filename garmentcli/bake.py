"""placeholder"""
import click


@click.command(name="bake")
def bake():
    """Not yet implemented."""
