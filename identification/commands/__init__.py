"""The command-line verbs of the five-axis story (``identify``, ``diagnose``, ``plan``, ``compensate``,
``verify``, ``observe``, ``sensor``, ``model``, ``demo`` ...): each module parses its options, calls the
sub-packages below and prints. ``kinid.cli`` imports a verb's module only when that verb runs.

Imports every other sub-package; nothing imports it but the roof.
"""

__all__: list = []
