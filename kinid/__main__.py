"""``python -m kinid`` is the ``kinid`` command."""
import sys

from .cli import main

sys.exit(main())
