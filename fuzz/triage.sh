#!/usr/bin/env bash
# Sorts the fuzzer's findings into Assimp's and ours:
#   fuzz/triage.sh FUZZER FINDINGS_DIR   (with the fuzz run's ASAN_OPTIONS and
#                                        LSAN_OPTIONS in the environment)
# Each crash-/timeout-/oom-/leak- file is run again; the report's first stack
# frame outside the sanitizer runtime, libc (named by its library, or by its
# source path when glibc's symbols are installed: string/..., sysdeps/...),
# libstdc++ and zlib says whose it is: libassimp -> "assimp" (the system's
# library, not instrumented: we cannot fix it, only report it), anything
# else -> "isk". UBSan reports and the harness's own findings are always
# ours. Prints one line per file and exits 1 when any finding is ours.
# Triaged files move to FINDINGS_DIR/assimp, FINDINGS_DIR/isk or
# FINDINGS_DIR/none (no report when run again).
set -uo pipefail
fuzzer=$1
dir=$2
ours=0
shopt -s nullglob
for input in "$dir"/crash-* "$dir"/timeout-* "$dir"/oom-* "$dir"/leak-*; do
  report=$(timeout 120 "$fuzzer" -timeout=30 -rss_limit_mb=4096 "$input" 2>&1)
  if ! grep -q -E "ERROR|SUMMARY|runtime error:|isk fuzz finding:" <<<"$report"; then
    owner=none  # passes when run again (a timeout on a busy machine)
    frame=""
  elif grep -q "runtime error:\|isk fuzz finding:\|uncaught exception" <<<"$report"; then
    owner=isk
    frame=$(grep -m1 "runtime error:\|isk fuzz finding:\|uncaught exception" <<<"$report")
  else
    frame=$(grep -E '^ +#[0-9]+ ' <<<"$report" |
      grep -v -E 'isk_import_fuzzer\+0x|libc\.so|libstdc\+\+|libz\.so|libgcc_s| (csu|string|sysdeps|stdlib|nptl|malloc)/' |
      head -n1)
    case "$frame" in
      *libassimp*) owner=assimp ;;
      "") owner=assimp  # no frame at all: a leak stack cut short in zlib
        frame=$(grep -m1 -E 'ERROR|SUMMARY' <<<"$report") ;;
      *) owner=isk ;;
    esac
  fi
  kind=$(grep -m1 -o -E 'SUMMARY: [A-Za-z]+: [a-z-]+|ERROR: libFuzzer: [a-z-]+' <<<"$report")
  echo "$owner $(basename "$input"): ${kind:-no report (passes now)}; ${frame# *}"
  mkdir -p "$dir/$owner"
  mv -f "$input" "$dir/$owner/"
  [ "$owner" = isk ] && ours=1
done
exit $ours
