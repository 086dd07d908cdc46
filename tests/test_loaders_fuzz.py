"""Property tests over every YAML loader a user feeds: terminal YAML, chain
files and IOC configs. Whatever the input, the answer is a loaded model or a
one-line `UserError` naming the file; never another exception."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from fastcs_ethercat.chain.file import parse_chain
from fastcs_ethercat.errors import UserError
from fastcs_ethercat.ioc.config import load_ioc_config
from fastcs_ethercat.terminals.files import parse_terminal_text
from tests.conftest import REPO_ROOT, TERMINALS_DIR

EL3104_TEXT = (TERMINALS_DIR / "EL3104.yaml").read_text()
DEMO_CHAIN_TEXT = (REPO_ROOT / "ioc" / "demo-chain.yaml").read_text()

_scalars = st.one_of(
    st.none(),
    st.booleans(),
    st.integers(min_value=-(2**40), max_value=2**40),
    st.floats(allow_nan=False),
    st.text(max_size=12),
)
_yaml_values = st.recursive(
    _scalars,
    lambda children: st.one_of(
        st.lists(children, max_size=4),
        st.dictionaries(st.text(min_size=1, max_size=10), children, max_size=4),
    ),
    max_leaves=20,
)


def _assert_one_line(error: UserError, name: str) -> None:
    message = str(error)
    assert "\n" not in message
    assert name in message


def _mutations(text: str) -> st.SearchStrategy[str]:
    """Real files with one line dropped, one line replaced, or cut short."""
    lines = text.splitlines(keepends=True)
    drop = st.integers(0, len(lines) - 1).map(
        lambda i: "".join(lines[:i] + lines[i + 1 :])
    )
    replace = st.tuples(st.integers(0, len(lines) - 1), st.text(max_size=20)).map(
        lambda pair: "".join([*lines[: pair[0]], pair[1] + "\n", *lines[pair[0] + 1 :]])
    )
    cut = st.integers(0, len(text)).map(lambda n: text[:n])
    return st.one_of(drop, replace, cut)


def _parse_or_user_error(parse: Any, text: str, name: str) -> None:
    try:
        parse(text, name)
    except UserError as error:
        _assert_one_line(error, name)


@settings(max_examples=60, deadline=None)
@given(_mutations(EL3104_TEXT))
def test_mutated_terminal_yaml_loads_or_fails_in_one_line(text: str) -> None:
    _parse_or_user_error(parse_terminal_text, text, "EL3104.yaml")


@settings(max_examples=60, deadline=None)
@given(_yaml_values)
def test_arbitrary_yaml_as_terminal_file(value: Any) -> None:
    _parse_or_user_error(parse_terminal_text, yaml.safe_dump(value), "x.yaml")


@settings(max_examples=60, deadline=None)
@given(_mutations(DEMO_CHAIN_TEXT))
def test_mutated_chain_loads_or_fails_in_one_line(text: str) -> None:
    _parse_or_user_error(parse_chain, text, "demo-chain.yaml")


@settings(max_examples=60, deadline=None)
@given(_yaml_values)
def test_arbitrary_yaml_as_chain(value: Any) -> None:
    _parse_or_user_error(parse_chain, yaml.safe_dump(value), "chain.yaml")


@settings(
    max_examples=60,
    deadline=None,
    suppress_health_check=[HealthCheck.function_scoped_fixture],
)
@given(_yaml_values)
def test_arbitrary_yaml_as_ioc_config(tmp_path: Path, value: Any) -> None:
    path = tmp_path / "ioc.yaml"
    path.write_text(yaml.safe_dump(value))
    try:
        load_ioc_config(path)
    except UserError as error:
        _assert_one_line(error, "ioc.yaml")
