#!/usr/bin/env bash
# Live capture of Unitree SDK2 (Python) low-level traffic on the loopback.
#
#   bash corpus/captures/capture.sh        (needs root for tcpdump)
#
# 1. tcpdump on lo (filter: udp) -> lowlevel.pcap
# 2. one subscriber process (all four topics) so that writers match and data
#    actually flows over UDP
# 3. publisher phase "default" (SDK Cyclone config as shipped), then phase
#    "frag" (same + MaxMessageSize 1456 B, which makes Cyclone send the 2092 B
#    hg LowState as DATA_FRAG)
# 4. rtps_extract.py: parse the pcap with our own RTPS parser, write
#    <topic>_<n>.cdr/.json and index.json, compare with cyclonedds bytes.
set -euo pipefail

HERE="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
ROOT="$(cd "$HERE/../.." && pwd)"
PY="${PYTHON:-$ROOT/.venv/bin/python}"
PCAP="$HERE/lowlevel.pcap"
WORK="$(mktemp -d)"
TCPDUMP_PID=""
SUB_PID=""

cleanup() {
    # stop only the processes started here, by PID
    [ -n "$SUB_PID" ] && kill "$SUB_PID" 2>/dev/null || true
    [ -n "$TCPDUMP_PID" ] && kill -INT "$TCPDUMP_PID" 2>/dev/null || true
    rm -rf "$WORK"
}
trap cleanup EXIT

# Remove the outputs of a previous run.
rm -f "$HERE"/*.cdr "$HERE"/rt_*.json "$HERE/index.json" "$HERE/published.json" "$PCAP"

# -U: write packets as they arrive; -Z root: keep permission to write here.
tcpdump -i lo -U -Z root -w "$PCAP" udp 2>"$WORK/tcpdump.err" &
TCPDUMP_PID=$!
sleep 1.5

"$PY" "$HERE/cap_pubsub.py" sub --seconds 60 >"$WORK/sub.log" 2>&1 &
SUB_PID=$!
sleep 1.5

for phase in default frag; do
    "$PY" "$HERE/cap_pubsub.py" pub --phase "$phase" --log "$HERE/published.json"
    sleep 1
done

# The subscriber exits by itself once it has seen every message.
wait "$SUB_PID" && sub_rc=0 || sub_rc=$?
SUB_PID=""
grep -v "take sample" "$WORK/sub.log" || true
sleep 1
kill -INT "$TCPDUMP_PID"
wait "$TCPDUMP_PID" || true
TCPDUMP_PID=""
cat "$WORK/tcpdump.err" >&2

"$PY" "$HERE/rtps_extract.py" "$PCAP" --published "$HERE/published.json" --out "$HERE"

# Independent view of the same file (Wireshark's dissector), if available.
if command -v tshark >/dev/null; then
    n=$(tshark -r "$PCAP" -T fields -e rtps.sm.id 2>/dev/null | tr ',' '\n' | grep -c '^0x16$' || true)
    echo "tshark sees $n DATA_FRAG submessages in $(basename "$PCAP")"
fi
[ "$sub_rc" -eq 0 ] || { echo "subscriber did not receive everything" >&2; exit 1; }
