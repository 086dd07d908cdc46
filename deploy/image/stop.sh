#!/bin/bash
# Stop the fastcs-ethercat IOC cleanly: the ioc-instance chart's default
# preStopExecutable (/epics/ioc/stop.sh, run with bash in the container).
#
# The container's first process (stdio-socket, in the chart's command) does
# not pass SIGTERM on, and the chart allows 3 s before SIGKILL: SIGTERM goes
# to the IOC itself (its PID from the heartbeat file), which closes its ADS
# connections and exits; this waits for that, at most
# FASTCS_ETHERCAT_STOP_WAIT_S (default 2.5) seconds.
file=${FASTCS_ETHERCAT_HEARTBEAT_FILE:-/tmp/fastcs-ethercat.heartbeat}
wait_s=${FASTCS_ETHERCAT_STOP_WAIT_S:-2.5}

if ! read -r pid _rest 2>/dev/null <"$file" || ! kill -TERM "$pid" 2>/dev/null; then
    echo "stop: no IOC to stop (no heartbeat file $file, or its PID is gone)"
    exit 0
fi
echo "stop: SIGTERM to the IOC (PID $pid)"
tenths=$(awk -v s="$wait_s" 'BEGIN { print int(s * 10) }')
for ((i = 0; i < tenths; i++)); do
    state=$(cut -d')' -f2- "/proc/$pid/stat" 2>/dev/null | cut -d' ' -f2)
    case $state in '' | Z | X) echo "stop: the IOC exited"; exit 0 ;; esac
    sleep 0.1
done
echo "stop: the IOC (PID $pid) still runs after ${wait_s} s"
exit 1
