"""``python -m detectors``: the registered detectors, or (``--markdown``) the parameter
reference docs/detectors.md (:func:`detectors.registry.main`)."""

import sys

from detectors.registry import main

sys.exit(main())
