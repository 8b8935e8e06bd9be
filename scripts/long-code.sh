#!/usr/bin/env bash
# Lists the functions longer than a limit (default 120 lines) and the files longer than another
# (default 800 lines) in src/ and exporters/, longest first (issue 20: a newcomer should be able to
# read each function whole). Functions come from universal-ctags' C++ parser with end lines
# (`--fields=+ne`), so a function is its body as the parser sees it, lambdas included; a file over
# the limit is marked "reason stated" when its first comment block says why it is one file
# ("One file:" at the start of a line of that block).
# usage: scripts/long-code.sh [FUNCTION_LINES [FILE_LINES]]
set -euo pipefail
cd "$(dirname "$0")/.."
function_limit=${1:-120}
file_limit=${2:-800}
mapfile -t files < <(git ls-files 'src/*.cpp' 'src/*.h' 'exporters/*.cpp' 'exporters/*.h')
echo "functions over ${function_limit} lines:"
ctags -x --_xformat='%n %e %N %F' --fields=+ne --kinds-c++=f --language-force=c++ "${files[@]}" |
    awk -v limit="$function_limit" '$2 != "" && $2 - $1 + 1 > limit {
        printf "%6d  %s  %s:%d\n", $2 - $1 + 1, $3, $4, $1 }' | sort -rn
echo "files over ${file_limit} lines:"
for f in "${files[@]}"; do
    lines=$(wc -l <"$f")
    if [ "$lines" -gt "$file_limit" ]; then
        reason=""
        if awk 'NR == 1, !/^\/\// { if (/^\/\/ One file:/) found = 1 } END { exit !found }' "$f"; then
            reason="  (reason stated)"
        fi
        printf "%6d  %s%s\n" "$lines" "$f" "$reason"
    fi
done | sort -rn
