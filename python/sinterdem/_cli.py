"""The ``sinterdem`` command installed with the wheel: the Rust command line, in-process."""

import sys


def main() -> None:
    """Runs ``sinterdem`` with ``sys.argv`` and exits with its exit code."""
    import signal

    from . import _native

    # the Rust handlers (stop after the current step, outputs written, exit 130/143) replace
    # Python's: ignore first, so that they do not chain to Python's KeyboardInterrupt
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    _native.install_signal_handlers()
    sys.exit(_native.cli_main(["sinterdem", *sys.argv[1:]]))


if __name__ == "__main__":
    main()
