"""The ``sensorgym`` command: one entry point with subcommands (see :mod:`.main`)."""
