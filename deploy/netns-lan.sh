#!/usr/bin/env bash
# netns-lan.sh: a simulated LAN on one host for rehearsing the vps cluster.
#
#   sudo deploy/netns-lan.sh up N        N hosts (namespaces vps-lan-h0 .. vps-lan-h{N-1}) on one bridge
#   sudo deploy/netns-lan.sh down        remove everything `up` made (safe to run twice)
#   sudo deploy/netns-lan.sh exec H CMD  run CMD inside host H (0-based index or namespace name)
#   sudo deploy/netns-lan.sh status      list the namespaces and their addresses
#
# Layout: a bridge `vpslan-br` lives in its own namespace `vps-lan-sw` (the "switch"), so nothing is
# added to the host's own network namespace. Host i is namespace `vps-lan-h$i` with address
# 10.77.0.$((i+1))/24 on eth0, joined to the bridge by a veth pair. The 10.77.0.0/24 addresses exist
# ONLY inside these namespaces; there is no route to or from the host or any real network.
# Host 0 is meant for the coordinator (10.77.0.1:7800), the others for workers.
#
# Link impairment (applied to every host's eth0, so a round trip crosses it twice), from the
# environment:
#   VPS_LAN_DELAY  (default 100us)   one-way delay
#   VPS_LAN_JITTER (default 50us)    delay jitter
#   VPS_LAN_LOSS   (default 1%)      packet loss
#   VPS_LAN_NETEM=0                  no impairment at all
# It becomes: tc qdisc add dev eth0 root netem delay $DELAY $JITTER loss $LOSS
set -euo pipefail

readonly PREFIX="vps-lan"
readonly SWITCH_NS="${PREFIX}-sw"
readonly BRIDGE="vpslan-br"
readonly SUBNET="10.77.0"
readonly MAX_HOSTS=200
DELAY="${VPS_LAN_DELAY:-100us}"
JITTER="${VPS_LAN_JITTER:-50us}"
LOSS="${VPS_LAN_LOSS:-1%}"
NETEM="${VPS_LAN_NETEM:-1}"

die() {
    echo "netns-lan.sh: $*" >&2
    exit 1
}

usage() {
    sed -n '2,8p' "$0" | sed 's/^# \{0,1\}//' >&2
    exit 2
}

require_tools() {
    [[ "$(id -u)" -eq 0 ]] || die "needs root (network namespaces, veth, tc): run it with sudo"
    command -v ip >/dev/null 2>&1 || die "the 'ip' command (iproute2) is missing: install iproute2"
    command -v tc >/dev/null 2>&1 || die "the 'tc' command (iproute2) is missing: install iproute2"
}

host_ns() { echo "${PREFIX}-h$1"; }

ns_exists() { ip netns list | awk '{print $1}' | grep -qx "$1"; }

our_namespaces() { ip netns list | awk '{print $1}' | grep -E "^${PREFIX}-(sw|h[0-9]+)$" || true; }

cmd_down() {
    local ns
    for ns in $(our_namespaces); do
        ip netns del "$ns"
        echo "removed namespace $ns"
    done
}

cmd_up() {
    local n="${1:-}"
    [[ "$n" =~ ^[0-9]+$ ]] && ((n >= 1 && n <= MAX_HOSTS)) || die "up: N must be a whole number 1..$MAX_HOSTS, got '${n}'"
    [[ -z "$(our_namespaces)" ]] || die "a simulated LAN already exists; run '$0 down' first"
    # Any failure (a failed command under set -e, or die) exits; undo the partial LAN then.
    trap 'echo "netns-lan.sh: up failed, removing what it made" >&2; cmd_down >/dev/null 2>&1 || true' EXIT

    ip netns add "$SWITCH_NS"
    ip -n "$SWITCH_NS" link set lo up
    if [[ "$NETEM" != "0" ]] && ! ip netns exec "$SWITCH_NS" tc qdisc add dev lo root netem delay 0us 2>/dev/null; then
        die "this kernel has no netem qdisc (sch_netem): load it (modprobe sch_netem), or run with VPS_LAN_NETEM=0 and impair in userspace with 'vps netem-relay' (deploy/README.md section 6)"
    fi
    ip -n "$SWITCH_NS" link add "$BRIDGE" type bridge
    ip -n "$SWITCH_NS" link set "$BRIDGE" up

    local i ns
    for ((i = 0; i < n; i++)); do
        ns="$(host_ns "$i")"
        ip netns add "$ns"
        ip -n "$ns" link set lo up
        # Create the pair inside the host namespace, then move the switch end out: the pair never
        # appears in the namespace this script was started from.
        ip -n "$ns" link add eth0 type veth peer name "p$i" netns "$SWITCH_NS"
        ip -n "$SWITCH_NS" link set "p$i" master "$BRIDGE" up
        ip -n "$ns" addr add "${SUBNET}.$((i + 1))/24" dev eth0
        ip -n "$ns" link set eth0 up
        if [[ "$NETEM" != "0" ]]; then
            ip netns exec "$ns" tc qdisc add dev eth0 root netem delay "$DELAY" "$JITTER" loss "$LOSS"
        fi
        echo "host $i: namespace $ns, address ${SUBNET}.$((i + 1))"
    done
    trap - EXIT
    if [[ "$NETEM" != "0" ]]; then
        echo "netem on every eth0: delay $DELAY $JITTER loss $LOSS"
    fi
}

cmd_exec() {
    local host="${1:-}"
    [[ -n "$host" ]] || die "exec: which host? (index or namespace name)"
    shift
    (($# > 0)) || die "exec: no command given"
    local ns="$host"
    [[ "$host" =~ ^[0-9]+$ ]] && ns="$(host_ns "$host")"
    [[ "$ns" =~ ^${PREFIX}-(sw|h[0-9]+)$ ]] || die "exec: '$host' is not a host of this LAN"
    ns_exists "$ns" || die "exec: namespace $ns does not exist (run '$0 up N' first)"
    exec ip netns exec "$ns" "$@"
}

cmd_status() {
    local ns
    for ns in $(our_namespaces); do
        echo "$ns: $(ip -n "$ns" -brief addr show | awk '$1 != "lo" {print $1, $3}' | tr '\n' ' ')"
    done
}

main() {
    (($# >= 1)) || usage
    local sub="$1"
    shift
    case "$sub" in
    up) require_tools; cmd_up "$@" ;;
    down) require_tools; cmd_down ;;
    exec) require_tools; cmd_exec "$@" ;;
    status) require_tools; cmd_status ;;
    -h | --help | help) usage ;;
    *) die "unknown subcommand '$sub' (up N | down | exec HOST CMD... | status)" ;;
    esac
}

main "$@"
