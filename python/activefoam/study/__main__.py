"""python3 -m activefoam.study: the study tool's command line (activefoam.study.cli)."""

import sys

from activefoam.study.cli import main

sys.exit(main())
