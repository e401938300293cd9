"""Builds the ego-vehicle FMUs into dist/fmi2/ and dist/fmi3/ (same as `sdl-fmu build`)."""

import sys

from sdl_fmu.cli import main

if __name__ == "__main__":
    sys.exit(main(["build", *sys.argv[1:]]))
