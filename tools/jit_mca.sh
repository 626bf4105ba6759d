#!/usr/bin/env bash
# Static throughput of JIT kernels with llvm-mca: a noise-free way to compare code generation
# changes on a shared, busy machine (not part of CI).
#
# Usage: tools/jit_mca.sh <graph.psg> [mcpu]      (mcpu defaults to znver3)
# Needs: a release build of psc (target/release/psc or $PSC), objdump, llvm-mca (Debian
# package llvm; any version 14+).
#
# Dumps each kernel psc bench compiles for the graph (the fused forward+adjoint first, then
# the forward), takes the longest branch-free run of instructions (the loop body: one
# iteration, 4 texels per vector group) and prints llvm-mca's cycles per texel and how many
# of them are waiting on register dependencies rather than execution resources.
set -euo pipefail
graph=${1:?usage: tools/jit_mca.sh <graph.psg> [mcpu]}
mcpu=${2:-znver3}
psc=${PSC:-target/release/psc}
mca=$(command -v llvm-mca || ls /usr/bin/llvm-mca-* 2>/dev/null | head -1)
[ -n "$mca" ] || { echo "llvm-mca not found" >&2; exit 1; }
dir=$(mktemp -d)
trap 'rm -rf "$dir"' EXIT
PSC_JIT_DUMP=$dir "$psc" bench "$graph" --size 16 --runs 1 >/dev/null 2>&1
for kind in "forward+adjoint:0" "forward:1"; do
    bin=$dir/kernel-${kind#*:}.bin
    objdump -D -b binary -mi386:x86-64 --no-show-raw-insn "$bin" |
        awk -F'\t' 'NF >= 2 && $1 ~ /:$/ { print $2 }' |
        awk '/^(j|ret)/ { if (n > best) { best = n; body = cur } n = 0; cur = ""; next }
             { n++; cur = cur $0 "\n" } END { printf "%s", body }' >"$dir/body.s"
    insts=$(wc -l <"$dir/body.s")
    "$mca" -mcpu="$mcpu" -iterations=20 -bottleneck-analysis "$dir/body.s" 2>/dev/null |
        awk -v kind="${kind%%:*}" -v insts="$insts" '
            /^Total Cycles:/ { cycles = $3 }
            /^Block RThroughput:/ { rt = $3 }
            /Data Dependencies:/ { gsub(/[\[\]%]/, ""); dep = $NF }
            END { printf "%-16s %6d instructions/iteration  %7.1f cycles/texel  (resource bound %6.1f; %s%% of cycles on dependencies)\n",
                         kind, insts, cycles / 20 / 4, rt / 4, dep }'
done
