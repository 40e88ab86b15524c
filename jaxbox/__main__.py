"""``python -m jaxbox`` runs the command line."""

from .cli import main

main()
