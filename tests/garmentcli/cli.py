"""Running the CLI in-process for the tests."""

from click.testing import CliRunner

from garmentcli.main import cli


def invoke(args):
    """CliRunner result of `garment ARGS` (each argument str()-ed).

    A `bake` that names neither --method nor --quality runs with --method lbs: these tests are about the command's inputs and
    outputs, for which the fast, exact method serves; the default method (the shipped model) has its own
    tests (test_bake_model.py, test_quickstart.py).
    """
    args = [str(a) for a in args]
    if args[:1] == ["bake"] and "--method" not in args and "--quality" not in args:
        args += ["--method", "lbs"]
    return CliRunner().invoke(cli, args)
