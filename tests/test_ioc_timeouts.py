"""`ads_timeout_ms`: the timeout of every ADS request of the IOC, from the config."""

from __future__ import annotations

from pathlib import Path

import pytest

from fastcs_ethercat.errors import UserError
from fastcs_ethercat.ioc.config import load_ioc_config


def _config(tmp_path: Path, extra: str) -> Path:
    path = tmp_path / "ioc.yaml"
    path.write_text(f"prefix: T\ntarget: 127.0.0.1\n{extra}")
    return path


def test_default_is_one_second(tmp_path: Path) -> None:
    assert load_ioc_config(_config(tmp_path, "")).ads_timeout_ms == 1000


def test_a_slow_plc_gets_a_longer_timeout(tmp_path: Path) -> None:
    config = load_ioc_config(_config(tmp_path, "ads_timeout_ms: 2500\n"))

    assert config.ads_timeout_ms == 2500


@pytest.mark.parametrize("value", ["0", "10", "70000", "fast"])
def test_bad_timeouts_are_one_line_naming_the_key(tmp_path: Path, value: str) -> None:
    with pytest.raises(UserError) as refused:
        load_ioc_config(_config(tmp_path, f"ads_timeout_ms: {value}\n"))

    assert "ads_timeout_ms" in str(refused.value)
