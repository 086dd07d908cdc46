"""No dead functions in the package: vulture over `src` at 60 %, with only
framework entry points whitelisted (`tests/vulture_whitelist.py`)."""

from __future__ import annotations

from pathlib import Path

import vulture

from tests.conftest import REPO_ROOT

LEFT_TO_OWNERS = {
    # the ADS client's API the tests and benchmarks/bench_ads_client.py use
    ("src/fastcs_ethercat/ads/client.py", "acquire_handles"),
    ("src/fastcs_ethercat/ads/client.py", "read_by_handles"),
    ("src/fastcs_ethercat/ads/client.py", "read_list_by_name"),
    ("src/fastcs_ethercat/ads/client.py", "add_notification"),
    ("src/fastcs_ethercat/ads/client.py", "delete_notification"),
}
"""What vulture still lists, each kept by its module's owner: no other name
may join them."""


def unused_functions() -> set[tuple[str, str]]:
    """(file, name) of each function or method vulture finds unused, as
    `vulture src tests/vulture_whitelist.py --min-confidence 60` lists them."""
    scan = vulture.Vulture()
    scan.scavenge(
        [str(REPO_ROOT / "src"), str(REPO_ROOT / "tests" / "vulture_whitelist.py")]
    )
    return {
        (Path(item.filename).relative_to(REPO_ROOT).as_posix(), item.name)
        for item in scan.get_unused_code(min_confidence=60)
        if item.typ in ("function", "method")
    }


def test_no_function_or_method_is_unused_beyond_the_known_few() -> None:
    unused = unused_functions()
    assert unused <= LEFT_TO_OWNERS, sorted(unused - LEFT_TO_OWNERS)
