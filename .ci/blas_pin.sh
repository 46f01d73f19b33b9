# Sourced by the scripts whose episodes must equal bit for bit across machines (.ci/leaderboard.sh,
# data/publish.sh). OpenBLAS chooses its kernels by CPU, and they round differently: on an AVX-512
# Intel (SkylakeX kernels) a dot product fuses its multiply-adds, on an AMD Zen (Haswell kernels)
# it does not, and the NMPCs' and ippo's closed loops carry that last bit to other final poses. The
# Haswell kernels run on every x86-64 CPU with AVX2 and FMA (Intel since 2013, every AMD Zen), so
# these scripts pin them there: their episodes then equal bit for bit on either (docs/ci.md,
# "Across machines"). An OPENBLAS_CORETYPE already set wins.
if [ -z "${OPENBLAS_CORETYPE:-}" ] && [ "$(uname -m)" = x86_64 ] \
    && grep -qw avx2 /proc/cpuinfo 2>/dev/null && grep -qw fma /proc/cpuinfo; then
    export OPENBLAS_CORETYPE=Haswell
fi
