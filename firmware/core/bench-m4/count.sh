#!/bin/sh
# Count the Cortex-M4F instructions of one `Compensator::cycle` call in QEMU.
# usage: ./count.sh            full reference workload (table + 8-sensor thermo-force + forces)
#        TABLE_ONLY=1 ./count.sh   table only
# Prints: bench m4_cycle_instructions <mean> (<label>)
set -e
cd "$(dirname "$0")"
export CARGO_TARGET_DIR="${CARGO_TARGET_DIR:-target}"
cargo build --release --target thumbv7em-none-eabihf --quiet
ELF="$CARGO_TARGET_DIR/thumbv7em-none-eabihf/release/axcomp-core-bench-m4"
LOG=$(mktemp)
qemu-system-arm -M mps2-an386 -cpu cortex-m4 -nographic \
  -semihosting-config enable=on,target=native -kernel "$ELF" \
  -singlestep -d exec,nochain -D "$LOG"
SYM=$(llvm-nm -S "$ELF" | awk '$4 == "one_cycle" { print $1, $2 }')
python3 - "$LOG" $SYM "${TABLE_ONLY:+table only}" <<'PY'
import re, sys
log, addr, size, label = sys.argv[1], int(sys.argv[2], 16), int(sys.argv[3], 16), sys.argv[4] if len(sys.argv) > 4 else ""
inside = calls = 0
for line in open(log):
    m = re.search(r'\[[0-9a-f]+/([0-9a-f]+)/', line)
    if not m:
        continue
    pc = int(m.group(1), 16)
    if addr <= pc < addr + size:
        inside += 1
        calls += pc == addr
print("bench m4_cycle_instructions %.1f (%s; %d calls, one_cycle %d bytes)"
      % (inside / calls, label or "table + 8-sensor thermo-force + 3 forces", calls, size))
PY
rm -f "$LOG"
