"""How the IOC puts its records into access security groups, and how a bad
ACF given to `fastcs-ethercat ioc` is reported (before anything connects)."""

from __future__ import annotations

from pathlib import Path

import pytest

from fastcs_ethercat.ioc.access import COE_GROUP, OUTPUTS_GROUP, access_group_of
from fastcs_ethercat.ioc.attributes import attribute_for_coe, attribute_for_point
from fastcs_ethercat.ioc.config import load_ioc_config
from fastcs_ethercat.ioc.plan import CoePoint, Point, PointKind
from tests.conftest import REPO_ROOT
from tests.processes import run_cli_child

OUTPUT = Point(
    key="m/s/out",
    symbol="Term 6 (EL2024).Channel 1",
    attribute="channel_1",
    type_name="BIT",
    kind=PointKind.BIT,
    index_group=0xF021,
    index_offset=8,
    byte_size=1,
    writable=True,
)
INPUT = Point(
    key="m/s/in",
    symbol="Term 5 (EL3104).AI Compact Channel 1",
    attribute="ai_compact_channel_1",
    type_name="INT",
    kind=PointKind.SCALAR,
    index_group=0xF030,
    index_offset=0,
    byte_size=2,
)
COE = CoePoint(
    attribute="ai_settings_filter",
    index=0x8000,
    subindex=6,
    type_name="BOOL",
    bit_size=1,
    writable=True,
)


def test_outputs_and_coe_parameters_get_their_groups() -> None:
    assert access_group_of(attribute_for_point(OUTPUT)) == OUTPUTS_GROUP
    assert access_group_of(attribute_for_coe(COE)) == COE_GROUP
    assert access_group_of(attribute_for_point(INPUT)) is None


def test_read_only_outputs_stay_in_default() -> None:
    assert access_group_of(attribute_for_point(OUTPUT, read_only=True)) is None
    assert access_group_of(attribute_for_coe(COE, read_only=True)) is None


def test_config_key_is_relative_to_the_config_file(tmp_path: Path) -> None:
    config = tmp_path / "ioc.yaml"
    config.write_text("prefix: T\ntarget: 127.0.0.1\naccess_security_file: s.acf\n")
    assert load_ioc_config(config).access_security_file == tmp_path / "s.acf"


@pytest.mark.e2e
def test_bad_acf_is_one_line_and_exit_2(tmp_path: Path) -> None:
    config = tmp_path / "ioc.yaml"
    config.write_text("prefix: T\ntarget: 127.0.0.1:9\nams_net_id: 127.0.0.1.1.1\n")
    acf = tmp_path / "site.acf"
    acf.write_text("ASG(DEFAULT) {\n    RULE(1, WRIT)\n}\n")
    done = run_cli_child("ioc", "--config", config, "--acf", acf, cwd=REPO_ROOT)
    assert done.returncode == 2
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and "site.acf" in lines[0], done.stderr
    assert "Traceback" not in done.stderr


@pytest.mark.e2e
def test_the_example_acf_is_valid() -> None:
    from fastcs_ethercat.ioc.access import check_acf

    check_acf(REPO_ROOT / "ioc" / "access-example.acf")
