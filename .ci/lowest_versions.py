"""Print pip constraints that pin every runtime dependency of pyproject.toml
to the lowest version its bound allows (`name>=X` -> `name==X`), so CI can
run the fast tier against them: the bounds are promises, this checks them."""

import re
import sys
import tomllib
from pathlib import Path

LOWER = re.compile(r"^([A-Za-z0-9_.-]+)(?:\[[^\]]*\])?\s*>=\s*([^,;\s]+)")


def main() -> None:
    project = tomllib.loads(Path(sys.argv[1]).read_text())["project"]
    for requirement in project["dependencies"]:
        found = LOWER.match(requirement)
        if found:
            print(f"{found.group(1)}=={found.group(2)}")


if __name__ == "__main__":
    main()
