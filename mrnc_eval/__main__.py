import sys

from mrnc_eval.cli import main

sys.exit(main())
