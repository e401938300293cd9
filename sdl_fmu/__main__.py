"""`python -m sdl_fmu`: the sdl-fmu command line."""

import sys

from .cli import main

sys.exit(main())
