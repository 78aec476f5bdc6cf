"""``python -m campaign.cli``: the ``fdd-campaign`` executable."""

from . import console_main

console_main()
