"""``python -m usdface.registry [--api]``: print the README's command table (or its table of
:mod:`usdface.api` functions), made from the declarations."""
import sys

from . import api_table, command_table

print(api_table() if "--api" in sys.argv[1:] else command_table(), end="")
