"""The ``cordis`` command (``cordis …`` or ``python -m cordis …``): the Rust CLI itself.

Example::

    cordis example rigid --out rigid.json
    python -m cordis simulate rigid.json --frames 100 --out rigid.csv
"""

import sys
from typing import List, Optional

from ._cordis import _cli_main


def main(argv: Optional[List[str]] = None) -> int:
    """Runs the command line on ``argv`` (default: ``sys.argv[1:]``); returns the exit code."""
    args = sys.argv[1:] if argv is None else list(argv)
    # Whatever Python printed must come out before the Rust side writes to the same streams.
    sys.stdout.flush()
    sys.stderr.flush()
    return _cli_main(["cordis", *args])


if __name__ == "__main__":
    sys.exit(main())
