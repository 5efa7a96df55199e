#!/usr/bin/env bash
# The dependency rule of docs/ARCHITECTURE.md, checked: the read side (crate reducem-core) pulls
# in no build-side or tool dependency and never names a build-side module, and the streaming
# writer never names the build side either; instruction-set-specific code stays in the tracer's
# kernels. The tool crates sit above the library: neither reducem nor pipeline depends on
# reducem-bench, reducem-core on neither tool crate, and nothing on the viewer. The crate
# boundary already makes most violations compile errors; this catches the rest (a new
# dependency, a path in a doc comment or a macro).
set -euo pipefail
cd "$(dirname "$0")/.."
failed=0

heavy='ply-rs|tobj|clap|zstd|indicatif|plotters|serde_json|toml|glam|png|embree|meshopt|reducem |reducem-gen |reducem-bench '
if cargo tree -p reducem-core -e normal --prefix none | grep -E "^($heavy)"; then
  echo "check_layering: reducem-core depends on the build side or a tool (above)" >&2
  failed=1
fi
# Dev-dependencies count too: a test of the library that needs the benchmarks belongs to them.
for crate in reducem pipeline; do
  if cargo tree -p "$crate" -e normal,dev --prefix none | grep -E '^reducem-bench '; then
    echo "check_layering: $crate depends on reducem-bench (above)" >&2
    failed=1
  fi
done

# The viewer (reducem-view) sits above everything: no crate of the workspace depends on it.
for crate in reducem-core reducem reducem-gen reducem-bench pipeline; do
  if cargo tree -p "$crate" -e normal,dev,build --prefix none | grep -E '^reducem-view '; then
    echo "check_layering: $crate depends on reducem-view (above)" >&2
    failed=1
  fi
done

build_side='(tools|conversion|build|strip_encoding|toplevel|input|stripify|chunking|quantize|mesh|gen|render|report|workload|baseline|inspect|decode)'
if grep -rnE "((crate|reducem|super)::$build_side|reducem_(gen|bench))\b" core/src; then
  echo "check_layering: the read side (core/src) names a build-side module (above)" >&2
  failed=1
fi
if grep -nE "crate::$build_side\b" src/format/writer.rs; then
  echo "check_layering: the format writer names a build-side module (above)" >&2
  failed=1
fi

# Intrinsics and functions compiled for a CPU feature belong to the kernels, beneath the walks.
if git ls-files '*.rs' | grep -v '^core/src/trace/kernel/' |
    xargs grep -nE '(std|core)::arch|#\[target_feature'; then
  echo "check_layering: instruction-set-specific code outside core/src/trace/kernel/ (above)" >&2
  failed=1
fi

# The pipeline's modules form layers (stages over jobs over manifests, errors and time as
# leaves): no two import each other, directly or around a circle.
if ! python3 scripts/module_cycles.py pipeline/src; then
  echo "check_layering: pipeline modules import one another in a circle (above)" >&2
  failed=1
fi

exit $failed
