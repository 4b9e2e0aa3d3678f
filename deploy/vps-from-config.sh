#!/usr/bin/env bash
# vps-from-config.sh: run `vps coordinator` or `vps worker` with flags taken from a config file.
#
#   deploy/vps-from-config.sh coordinator configs/coordinator.toml [EXTRA VPS FLAGS...]
#   deploy/vps-from-config.sh worker      configs/worker.toml      [EXTRA VPS FLAGS...]
#   VPS_DRY_RUN=1 deploy/vps-from-config.sh ...   print the command instead of running it
#   VPS_BIN=/path/to/vps                          the binary (default: vps on PATH)
#
# The vps CLI does not read these files; this script is the only reader. It understands only
# `key = "value"` lines (see the comments in configs/*.toml); unknown keys are an error, so a typo
# does not silently fall back to a default. An empty value leaves the flag out.
set -euo pipefail

die() {
    echo "vps-from-config.sh: $*" >&2
    exit 1
}

(($# >= 2)) || die "usage: $0 coordinator|worker CONFIG [EXTRA VPS FLAGS...]"
role="$1"
config="$2"
shift 2
[[ -r "$config" ]] || die "cannot read config file '$config'"

case "$role" in
coordinator)
    # key:flag pairs, in the order the flags are passed.
    keys=(listen:--listen cert:--cert key:--key pin:--pin workers:--workers device:--device
        seconds:--seconds threads:--threads voxel_size:--voxel-size haptic_config:--config record:--record report:--report
        equal_shares:--equal-shares spin_us:--spin-us max_stale_frames:--max-stale-frames)
    ;;
worker)
    keys=(coordinator:--coordinator cert:--cert key:--key pin:--pin cache:--cache threads:--threads)
    ;;
*) die "role must be 'coordinator' or 'worker', got '$role'" ;;
esac

# Every non-blank, non-comment line must be `key = "value"`; report the first that is not.
declare -A values=()
line_no=0
while IFS= read -r line || [[ -n "$line" ]]; do
    line_no=$((line_no + 1))
    stripped="$(sed -e 's/^[[:space:]]*//' -e 's/[[:space:]]*$//' <<<"$line")"
    [[ -z "$stripped" || "$stripped" == \#* ]] && continue
    if [[ "$stripped" =~ ^([a-z_]+)[[:space:]]*=[[:space:]]*\"([^\"]*)\"[[:space:]]*(#.*)?$ ]]; then
        name="${BASH_REMATCH[1]}"
        value="${BASH_REMATCH[2]}"
    else
        die "$config:$line_no: expected key = \"value\", got: $stripped"
    fi
    known=0
    for pair in "${keys[@]}"; do [[ "${pair%%:*}" == "$name" ]] && known=1; done
    ((known)) || die "$config:$line_no: unknown key '$name' for a $role"
    values[$name]="$value"
done <"$config"

args=("$role")
for pair in "${keys[@]}"; do
    name="${pair%%:*}"
    flag="${pair#*:}"
    value="${values[$name]:-}"
    [[ -n "$value" ]] || continue
    if [[ "$name" == "equal_shares" ]]; then
        # A switch: "true" passes it, "false" leaves it out.
        case "$value" in
        true) args+=("$flag") ;;
        false) ;;
        *) die "$config: equal_shares must be \"true\" or \"false\", got '$value'" ;;
        esac
    elif [[ "$name" == "pin" ]]; then
        if [[ -d "$value" ]]; then
            shopt -s nullglob
            pins=("$value"/*.crt)
            shopt -u nullglob
            ((${#pins[@]} > 0)) || die "$config: pin directory '$value' holds no .crt files"
            for p in "${pins[@]}"; do args+=(--pin "$p"); done
        else
            args+=(--pin "$value")
        fi
    else
        args+=("$flag" "$value")
    fi
done
args+=("$@")

bin="${VPS_BIN:-vps}"
if [[ "${VPS_DRY_RUN:-0}" != "0" ]]; then
    printf '%q ' "$bin" "${args[@]}"
    echo
    exit 0
fi
exec "$bin" "${args[@]}"
