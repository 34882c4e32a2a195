"""The ``emmi-gym`` subcommands of the tools that read and compare results: scoring a run's checkpoints,
drawing learning curves, comparing scripted policies. Each module builds its subcommand's parser
(``add_parser``) and runs it (``run``), importing the heavy packages only when it runs."""
