#!/bin/sh
# Runs one libFuzzer target for a bounded time: run_fuzzer.sh FUZZER SEED_DIR WORK_DIR SECONDS
# [SKIP_REASON]. New inputs go to WORK_DIR/corpus (the seed folder is only read), findings
# (crash-*, leak-*, timeout-*, oom-*) to WORK_DIR/findings/. Exit 0 when nothing was found, 77
# (CTest: skipped) with the reason when SKIP_REASON is given, 1 with how to reproduce otherwise.
# Used by CTest's fuzz.run.NAME tests and by scripts/fuzz.
set -u
fuzzer=$1 seeds=$2 work=$3 seconds=$4 skip=${5:-}
if [ -n "$skip" ]; then
    echo "SKIPPED: $skip"
    exit 77
fi
if [ ! -x "$fuzzer" ]; then
    echo "no fuzzer at $fuzzer (the clang build failed?)"
    exit 1
fi
mkdir -p "$work/corpus" "$work/findings"
# A target's dictionary (tests/fuzz/dict/NAME.dict), when it has one, steers the mutations.
dict=$(dirname "$0")/dict/$(basename "$fuzzer" _fuzzer).dict
dict_arg=
[ -f "$dict" ] && dict_arg="-dict=$dict"
# Leak checks stay on; ASan's own allocator limit keeps a huge allocation a finding (oom-*).
ASAN_OPTIONS=${ASAN_OPTIONS:-allocator_may_return_null=0} \
UBSAN_OPTIONS=${UBSAN_OPTIONS:-print_stacktrace=1} \
"$fuzzer" -max_total_time="$seconds" -rss_limit_mb=2048 -malloc_limit_mb=2048 -timeout=10 \
    -print_final_stats=1 -artifact_prefix="$work/findings/" $dict_arg "$work/corpus" "$seeds"
status=$?
if [ $status -ne 0 ]; then
    name=$(basename "$fuzzer" _fuzzer)
    echo
    echo "FUZZ FINDING (exit $status) in $work/findings/:"
    ls -l "$work/findings/"
    echo "reproduce: $fuzzer FILE   (or the gcc build's tests/fuzz/${name}_replay FILE)"
    echo "keep it: copy FILE to tests/fuzz/corpus/$name/ once the loader is fixed"
    exit 1
fi
exit 0
