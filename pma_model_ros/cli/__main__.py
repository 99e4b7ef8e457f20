"""``python -m pma_model_ros.cli``: the ``pma-model`` command."""

import sys

from .main import main

sys.exit(main())
