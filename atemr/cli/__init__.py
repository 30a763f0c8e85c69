"""The ``atemr`` command line: one module per subcommand, named in `atemr.cli.main.BUILTIN_COMMANDS`."""
