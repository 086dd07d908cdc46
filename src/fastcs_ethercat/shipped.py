"""Files that ship with fastcs-ethercat: the terminal types and the demo's.

In a wheel they are package data under `fastcs_ethercat/data/`; in a
checkout `data/terminals` and `data/ioc` are links to the repository's
`terminals/` and `ioc/`. A pip-installed IOC, an editable install and the
image therefore find the same defaults, whatever the working directory.
"""

from __future__ import annotations

from pathlib import Path
from typing import Final

DATA_DIR: Final = Path(__file__).parent / "data"
BUILTIN_TERMINALS_DIR: Final = DATA_DIR / "terminals"
"""One YAML file per terminal type in use at Diamond (`terminals/`)."""
EXAMPLES_DIR: Final = DATA_DIR / "ioc"
DEMO_CONFIG: Final = EXAMPLES_DIR / "demo.yaml"
DEMO_CHAIN: Final = EXAMPLES_DIR / "demo-chain.yaml"
