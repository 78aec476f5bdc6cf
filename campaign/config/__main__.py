"""``python -m campaign.config``: the campaign-file reference, starting file and check."""

from .docs import main

raise SystemExit(main())
