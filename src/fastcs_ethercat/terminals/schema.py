"""The JSON schema of terminal YAML files, for editors (yaml-language-server).

Each generated YAML file starts with `# yaml-language-server: $schema=
schema.json`, so an editor opened on `terminals/` completes and checks keys.
The schema comes from the pydantic models, so it cannot drift from them.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from pydantic import RootModel

from fastcs_ethercat.terminals.model import TerminalType
from fastcs_ethercat.terminals.yaml_io import SCHEMA_FILE_NAME

SCHEMA_DIALECT = "https://json-schema.org/draft/2020-12/schema"


# Here, not with the models: making this class builds every model's
# validator, which nothing needs at an IOC's start (the docstring is the
# schema's description).
class TerminalFile(RootModel[dict[str, TerminalType]]):
    """A terminal YAML file: terminal type name -> its description."""


def terminal_schema() -> dict[str, Any]:
    """The JSON schema of one terminal YAML file (our layout)."""
    schema = TerminalFile.model_json_schema()
    return {
        "$schema": SCHEMA_DIALECT,
        "title": "fastcs-ethercat terminal types",
        "description": (
            "Terminal type name (e.g. EL3104) -> its description, generated "
            "from Beckhoff ESI XML by `fastcs-ethercat terminals generate`."
        ),
        **{key: value for key, value in schema.items() if key != "title"},
    }


def schema_text() -> str:
    """The schema as the text written to `schema.json`."""
    return json.dumps(terminal_schema(), indent=2, ensure_ascii=False) + "\n"


def write_schema(directory: Path) -> Path:
    """Write `schema.json` into `directory` (unchanged files are not touched)."""
    path = directory / SCHEMA_FILE_NAME
    text = schema_text()
    if not path.exists() or path.read_text(encoding="utf-8") != text:
        path.write_text(text, encoding="utf-8")
    return path
