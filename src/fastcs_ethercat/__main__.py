"""`fastcs-ethercat` and `python -m fastcs_ethercat`: the CLI, its imports
made with the collector held (see `collector.hold`; each command releases it)."""

from fastcs_ethercat import collector


def main() -> None:
    """The `fastcs-ethercat` entry point."""
    collector.hold()
    from fastcs_ethercat.cli import app

    app()


if __name__ == "__main__":
    main()
