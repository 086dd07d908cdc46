#!/usr/bin/env bash
# Build the fastcs-ethercat image with podman on a machine with no container
# registry and no Docker engine (only Debian's and PyPI's package
# repositories), exactly as tests/test_container.py does:
#
#   deploy/build-image.sh TAG
#
# 1. A base image with Python 3.11, made once from Debian packages with
#    debootstrap and kept (podman image exists), unless BASE_IMAGE names one.
# 2. The locked dependencies and the fastcs-ethercat wheel, downloaded and
#    built on this host with its own pip settings (build/wheelhouse and
#    build/app), by the pip of deploy/build-pip.lock in a venv of its own
#    (build/pip-venv): the host's pip may be too old for the lock. The
#    version is setuptools-scm's (the git tag's): the wheel's, the label's.
# 3. podman build with WHEELS=context: no network inside the build.
#
# podman runs through deploy/podman.sh (the options this machine needs).
# Needs: podman, runc, debootstrap (apt-get install podman runc debootstrap),
# and root for debootstrap. Environment: BASE_IMAGE (default
# localhost/fastcs-ethercat-base:bookworm), DEBIAN_MIRROR (default: the first
# Debian mirror of apt's sources), PYTHON (default python3).
set -euo pipefail

if [[ $# -ne 1 ]]; then
    echo "usage: $0 TAG" >&2
    exit 2
fi
TAG=$1
REPO=$(cd "$(dirname "$0")/.." && pwd)
BASE_IMAGE=${BASE_IMAGE:-localhost/fastcs-ethercat-base:bookworm}
PYTHON=${PYTHON:-python3}
PODMAN=("$REPO/deploy/podman.sh")

say() { echo "build-image: $*" >&2; }

debian_mirror() {
    if [[ -n ${DEBIAN_MIRROR:-} ]]; then
        echo "$DEBIAN_MIRROR"
        return
    fi
    local uri
    uri=$(grep -hoE '(URIs:|^deb) +https?://[^ ]+' \
        /etc/apt/sources.list.d/*.sources /etc/apt/sources.list 2>/dev/null \
        | awk '{print $2}' | grep -v security | head -n 1 || true)
    echo "${uri:-http://deb.debian.org/debian}"
}

build_base() {
    local rootfs
    rootfs=$(mktemp -d)
    trap 'rm -rf "$rootfs"' RETURN
    chmod 755 "$rootfs" # becomes the image's /: every user must enter it
    say "making $BASE_IMAGE with debootstrap (a few minutes, once per machine)"
    debootstrap --variant=minbase --include=python3,python3-venv \
        bookworm "$rootfs" "$(debian_mirror)" >&2
    rm -rf "$rootfs"/var/cache/apt/archives/*.deb "$rootfs"/var/lib/apt/lists/*
    tar -C "$rootfs" -c . | "${PODMAN[@]}" import - "$BASE_IMAGE" >&2
}

if [[ $BASE_IMAGE == localhost/* ]] && ! "${PODMAN[@]}" image exists "$BASE_IMAGE"; then
    build_base
fi

# The pip that builds, whatever the host's is (kept while its lock is the same).
PIP_LOCK=$REPO/deploy/build-pip.lock
PIP_VENV=$REPO/build/pip-venv
PIP_HASH=$(sha256sum "$PIP_LOCK" | cut -d' ' -f1)
if [[ $(cat "$PIP_VENV/.lock-sha256" 2>/dev/null) != "$PIP_HASH" ]]; then
    say "a venv with the pip of $(basename "$PIP_LOCK")"
    rm -rf "$PIP_VENV"
    "$PYTHON" -m venv "$PIP_VENV"
    "$PIP_VENV/bin/python" -m pip install --quiet --require-hashes \
        --requirement "$PIP_LOCK"
    echo "$PIP_HASH" >"$PIP_VENV/.lock-sha256"
fi
PIP=("$PIP_VENV/bin/python" -m pip)

WHEELHOUSE=$REPO/build/wheelhouse
APP=$REPO/build/app
LOCK=$REPO/deploy/requirements.lock
# The wheelhouse is kept while the lock is the same (its hash is stored in it).
LOCK_HASH=$(sha256sum "$LOCK" | cut -d' ' -f1)
if [[ $(cat "$WHEELHOUSE/.lock-sha256" 2>/dev/null) != "$LOCK_HASH" ]]; then
    say "wheels of the locked dependencies"
    rm -rf "$WHEELHOUSE"
    mkdir -p "$WHEELHOUSE"
    "${PIP[@]}" wheel --quiet --require-hashes --requirement "$LOCK" \
        --wheel-dir "$WHEELHOUSE"
    echo "$LOCK_HASH" >"$WHEELHOUSE/.lock-sha256"
fi
say "the fastcs-ethercat wheel"
rm -rf "$APP"
mkdir -p "$APP"
"${PIP[@]}" wheel --quiet --no-deps --wheel-dir "$APP" "$REPO"
# setuptools-scm's version of the checkout (from its git tag), as the wheel's
# name carries it: the image label says the same.
WHEEL=$(basename "$APP"/fastcs_ethercat-*.whl)
VERSION=${WHEEL#fastcs_ethercat-}
VERSION=${VERSION%%-*}

say "podman build -t $TAG (version $VERSION)"
# --layers=false: one commit at the end, not one per instruction (each is a
# full copy of the image with the vfs storage driver).
"${PODMAN[@]}" build --network host --layers=false \
    --build-arg "BASE_IMAGE=$BASE_IMAGE" \
    --build-arg WHEELS=context \
    --build-arg "VERSION=$VERSION" \
    --tag "$TAG" "$REPO" >&2
say "built $TAG"
