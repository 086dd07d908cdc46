#!/usr/bin/env bash
# podman with the options a machine like ours needs (the kernel setup refuses
# podman's defaults): vfs storage, runc with cgroupfs, and explicit ulimits
# (never above the caller's) for `build`, `run` and `create`; `kube` (play)
# takes no --ulimit, so its containers get them as containers.conf defaults.
#
#   deploy/podman.sh run --rm --network host fastcs-ethercat:local demo
set -euo pipefail

at_most() {
    local limit=$1 cap=$2
    if [[ $limit == unlimited || $limit -gt $cap ]]; then
        limit=$cap
    fi
    echo "$limit"
}

OPTIONS=(--storage-driver vfs --runtime runc --cgroup-manager cgroupfs)
NOFILE=$(at_most "$(ulimit -n)" 20000)
NPROC=$(at_most "$(ulimit -u)" 10000)
LIMITS=(--ulimit "nofile=${NOFILE}:${NOFILE}" --ulimit "nproc=${NPROC}:${NPROC}")

command=${1:?usage: $0 PODMAN-COMMAND [ARGS...]}
shift
case $command in
    build | run | create) exec podman "${OPTIONS[@]}" "$command" "${LIMITS[@]}" "$@" ;;
    kube)
        conf=$(mktemp)
        trap 'rm -f "$conf"' EXIT
        printf '[containers]\ndefault_ulimits = ["nofile=%s:%s", "nproc=%s:%s"]\n' \
            "$NOFILE" "$NOFILE" "$NPROC" "$NPROC" >"$conf"
        CONTAINERS_CONF=${CONTAINERS_CONF:-$conf} podman "${OPTIONS[@]}" kube "$@"
        ;;
    *) exec podman "${OPTIONS[@]}" "$command" "$@" ;;
esac
