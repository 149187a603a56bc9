"""Console script: the same command line as the ``slam2world`` binary."""

import os
import sys

from slam2world._slam2world import run_cli


def main() -> None:
    """Runs ``slam2world`` with ``sys.argv`` and exits with its code."""
    # `slam2world demo` draws its figures with this interpreter (matplotlib, slam2world.plot).
    os.environ.setdefault("SLAM2WORLD_PYTHON", sys.executable)
    if sys.argv[1:2] == ["batch"]:
        # Ray runs in Python: the batch path is the package's own.
        from slam2world.batch import main as batch_main

        sys.exit(batch_main(sys.argv[2:]))
    try:
        code = run_cli(["slam2world", *sys.argv[1:]])
    except KeyboardInterrupt:
        # The run said so on stderr and left the previous outputs as they were.
        code = 130
    sys.exit(code)


if __name__ == "__main__":
    main()
