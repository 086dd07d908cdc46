#!/bin/sh
# Regenerate terminals/*.yaml from the ESI files; run from the repository root.
# New types of the list are generated with default choices; existing files are
# regenerated keeping their choices (selected flags, PDO group, CoE choices).
set -e
ESI="--esi ../shared/esi --esi tests/data/esi/EL3356-0010-fixture.xml"
TYPES="EK1100 EK1122 EL1014 EL1084 EL1124 EL1502 EL2024 EL2124 EL3104 EL3124
EL3202 EL3314 EL3356-0010 EL3602 EL3702 EL4134 EL4732 ELM3704-0000
EP3174-0002 EP4374-0002"
# shellcheck disable=SC2086  # word splitting of ESI and TYPES is intended
fastcs-ethercat terminals generate $TYPES $ESI --out terminals --skip-existing
# shellcheck disable=SC2086
fastcs-ethercat terminals regenerate terminals $ESI
