import sys

from mrnc_eval import gc_pause

if __name__ == "__main__":  # not when merely imported (a tool importing every module would run with gc off)
    gc_pause.pause(one_command=True)  # the CLI's imports too; cli._dispatch resumes it at once for any verb but `slam`

from mrnc_eval.cli import main  # after the pause

if __name__ == "__main__":
    sys.exit(main())
