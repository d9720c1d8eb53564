#!/usr/bin/env bash
# The code's shape, as issue 26 measured it: non-test source files over 600/800/1000
# lines (lines before a file's first `#[cfg(test)]`), functions over 100/150 lines (the
# six longest listed), and public items per crate (`pub fn/struct/enum/const/type/trait/
# static/mod/use` lines under each crate's src/). Test files (`tests.rs`, `tests/`) are
# not counted. Usage: benches/code_shape.sh [TREE] (default: this checkout).
set -euo pipefail
cd "${1:-$(dirname "$0")/..}"
files=$(git ls-files 'crates/*.rs' | grep -v '/tests/\|/benches/\|/examples/\|/tests\.rs$')
o600=0; o800=0; o1000=0
for f in $files; do
  n=$(awk '/^#\[cfg\(test\)\]/{exit} {c++} END{print c+0}' "$f")
  [ "$n" -gt 600 ] && o600=$((o600 + 1))
  [ "$n" -gt 800 ] && o800=$((o800 + 1))
  [ "$n" -gt 1000 ] && o1000=$((o1000 + 1))
done
echo "non-test files over 600 lines: $o600, over 800: $o800, over 1000: $o1000"
lens=$(for f in $files; do awk -v F="$f" '
/^#\[cfg\(test\)\]/{exit}
match($0,/^( *)(pub(\([a-z: ]+\))? )?(const )?(unsafe )?fn [a-zA-Z_0-9]+/){ if(name==""){s=$0; sub(/^ */,"",s); name=s; start=NR; match($0,/^ */); indent=RLENGTH; } }
name!="" && NR>start && $0 ~ "^" sprintf("%" indent "s","") "}$" { print NR-start+1, F":"start, substr(name,1,45); name="" }
' "$f"; done | sort -rn)
echo "functions over 150 lines: $(awk '$1>150' <<<"$lens" | wc -l), over 100: $(awk '$1>100' <<<"$lens" | wc -l)"
head -6 <<<"$lens"
for c in crates/*/; do
  n=$(grep -rhE '^\s*pub (fn|struct|enum|const|type|trait|static|mod|use|unsafe fn) ' "$c/src" 2>/dev/null | wc -l)
  echo "public items $(basename "$c"): $n"
done
