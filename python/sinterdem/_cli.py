"""The ``sinterdem`` command installed with the wheel: the Rust command line, in-process."""

import sys


def main() -> None:
    """Runs ``sinterdem`` with ``sys.argv`` and exits with its exit code."""
    from . import _native

    sys.exit(_native.cli_main(["sinterdem", *sys.argv[1:]]))


if __name__ == "__main__":
    main()
