import sys

from mrnc_eval import gc_pause

gc_pause.pause(one_command=True)  # the CLI's imports too; cli._dispatch resumes it at once for any verb but `slam`

from mrnc_eval.cli import main  # noqa: E402 - after the pause

if __name__ == "__main__":
    sys.exit(main())
