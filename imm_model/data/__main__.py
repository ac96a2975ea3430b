"""`python -m imm_model.data build-sample|summary` (same as `imm data ...`)."""

import sys

from imm_model.cli import main

if __name__ == "__main__":
    sys.exit(main(["data", *sys.argv[1:]]))
