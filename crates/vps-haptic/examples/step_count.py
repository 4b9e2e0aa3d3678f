# Counts the instructions a function executes by single-stepping it in gdb: for code valgrind
# cannot run (the kernel's AVX-512 copy; valgrind has no AVX-512 and hides it from CPUID, so under
# callgrind the kernel runs its AVX2 copy). Agrees with callgrind within 0.3 % on the AVX2 copy.
# Slow (about 1,500 instructions per second): use small shells.
#
#   SYMS=$(nm target/release/examples/kernel_ir | grep accumulate_avx512 | awk '{print $3}' | paste -sd,)
#   SYMS=$SYMS gdb -q -batch -x crates/vps-haptic/examples/step_count.py \
#       --args target/release/examples/kernel_ir 1000 contact 1
#
# SYMS: comma-separated (mangled) symbols; every call of each is counted, callees included, from
# its first instruction until it returns. Prints "RESULT calls=C instructions=I". MAXCALLS (optional):
# stop after that many calls (e.g. the first 4 of the fine shell's 64 classes: classes are cyclic,
# so their points are alike; divide by those classes' points).
import os

import gdb

gdb.execute("set pagination off")
gdb.execute("set confirm off")
gdb.execute("starti", to_string=True)
for sym in os.environ["SYMS"].split(","):
    gdb.execute("break *'" + sym + "'")
gdb.execute("continue", to_string=True)


def register(name):
    return int(gdb.parse_and_eval("$" + name))


total = 0
calls = 0
max_calls = int(os.environ.get("MAXCALLS") or "0")
while gdb.selected_inferior().pid:
    sp = register("rsp")
    ret = int.from_bytes(gdb.selected_inferior().read_memory(sp, 8).tobytes(), "little")
    while True:
        gdb.execute("stepi", to_string=True)
        total += 1
        if register("pc") == ret and register("rsp") == sp + 8:
            break
    calls += 1
    if calls == max_calls:
        gdb.execute("kill", to_string=True)
        break
    try:
        gdb.execute("continue", to_string=True)
    except gdb.error:
        break
print("RESULT calls=%d instructions=%d" % (calls, total))
