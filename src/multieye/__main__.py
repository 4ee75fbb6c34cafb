"""``python -m multieye``: the command line (:mod:`multieye.cli`)."""

from multieye.cli import main

if __name__ == "__main__":
    main()
