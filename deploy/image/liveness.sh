#!/bin/bash
# Liveness of the fastcs-ethercat IOC: the ioc-instance chart's default
# livenessExecutable (/epics/ioc/liveness.sh, run with bash in the container).
#
# Passes while the IOC's 1 s health scan runs (the one that moves HEARTBEAT),
# whether or not the PLC answers: a PLC that is away is an alarm, not a
# restart. Before it serves (waiting for a PLC that is away at its first
# start), the IOC rewrites the file every second all the same. Fails when the IOC process is gone, stopped, or its heartbeat file
# is older than FASTCS_ETHERCAT_LIVENESS_MAX_AGE_S (default 15): a hung event
# loop. Pure bash and /proc, well inside Kubernetes' 1 s probe timeout.
file=${FASTCS_ETHERCAT_HEARTBEAT_FILE:-/tmp/fastcs-ethercat.heartbeat}
max_age=${FASTCS_ETHERCAT_LIVENESS_MAX_AGE_S:-15}

if ! read -r pid _count stamp 2>/dev/null <"$file"; then
    echo "liveness: no heartbeat file $file (the IOC has not started)"
    exit 1
fi
state=$(cut -d')' -f2- "/proc/$pid/stat" 2>/dev/null | cut -d' ' -f2)
case $state in
    '' | Z | X) echo "liveness: the IOC (PID $pid) is gone"; exit 1 ;;
    T | t) echo "liveness: the IOC (PID $pid) is stopped"; exit 1 ;;
esac
age=$(($(date +%s) - ${stamp%.*}))
if ((age > max_age)); then
    echo "liveness: the IOC's heartbeat is ${age} s old (more than ${max_age} s): hung"
    exit 1
fi
exit 0
