"""The ``satsight`` command's subcommands, grouped by what they work on; ``satsight.cli``
assembles them."""
