"""The ``emmi-gym`` subcommands, one module each: the module builds its subcommand's parser
(``add_parser``) and runs it (``run``), importing the heavy packages only when it runs; their argument
types (:mod:`.arguments`) and what turns a command's outcome into a line and an exit status
(:mod:`.dispatch`)."""
