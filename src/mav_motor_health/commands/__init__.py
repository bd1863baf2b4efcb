"""Subcommands of the ``mav-motor-health`` CLI (each a thin shell over a library function)."""
