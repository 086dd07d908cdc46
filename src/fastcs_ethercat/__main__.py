"""`python -m fastcs_ethercat`: the same CLI as `fastcs-ethercat`."""

from fastcs_ethercat.cli import app

if __name__ == "__main__":
    app()
