"""``python -m usdface.registry``: print the README's command table (made from the declarations)."""
from . import command_table

print(command_table(), end="")
