"""placeholder"""
import click


@click.command(name="examples")
def examples():
    """Not yet implemented."""
