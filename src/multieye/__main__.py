"""``python -m multieye``: the command line (:mod:`multieye.cli`)."""

from multieye.cli import run

if __name__ == "__main__":
    run()
