"""The `garment` command line: one thin module per subcommand."""
