"""placeholder"""
import click


@click.command(name="metrics")
def metrics():
    """Not yet implemented."""
