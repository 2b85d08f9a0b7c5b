import sys

from mrnc_eval.cli import main

if __name__ == "__main__":
    sys.exit(main())
