"""No dead code in the package: vulture over `src` at 60 %, with only
framework entry points whitelisted (`tests/vulture_whitelist.py`), finds no
unused class, property, function or method beyond the few kept below."""

from __future__ import annotations

from pathlib import Path

import vulture

from tests.conftest import REPO_ROOT

CLIENT_API = {
    ("src/fastcs_ethercat/ads/client.py", name)
    for name in (
        "acquire_handles",
        "read_by_handles",
        "read_list_by_name",
        "add_notification",
        "delete_notification",
    )
}
"""`AdsClient`'s public API beyond what the IOC calls: symbols by handle and
notifications as `docs/explanations/ads-client.md` describes them, and
`read_list_by_name` with pyads' name and answer, the calls a script that
used pyads makes. The IOC itself batches handles its own way
(`ioc/handles.py`) and polls instead of being notified; the tests and
`benchmarks/bench_ads_client.py` (the client against pyads) call these. Removing
`add_notification` would leave the client's notification dispatch
(`AdsClient.notified`) with nothing to dispatch."""
KEPT = CLIENT_API
"""What vulture may still list: no other name may join them."""
KINDS = ("class", "property", "function", "method")


def unused_code() -> set[tuple[str, str]]:
    """(file, name) of each class, property, function or method vulture finds
    unused, as `vulture src tests/vulture_whitelist.py --min-confidence 60`
    lists them."""
    scan = vulture.Vulture()
    scan.scavenge(
        [str(REPO_ROOT / "src"), str(REPO_ROOT / "tests" / "vulture_whitelist.py")]
    )
    return {
        (Path(item.filename).relative_to(REPO_ROOT).as_posix(), item.name)
        for item in scan.get_unused_code(min_confidence=60)
        if item.typ in KINDS
    }


def test_nothing_is_unused_beyond_the_kept_few() -> None:
    unused = unused_code()
    assert unused <= KEPT, sorted(unused - KEPT)
