#!/usr/bin/env bash
# Benchmarks horus-gen against capnp compile and lcm-gen on the same 35-message package, and the
# -fsyntax-only cost of the generated headers. Writes bench/generator/RESULTS.md.
# Usage: bench/generator/run.sh [--gen-reps N] [--cxx-reps N]
set -euo pipefail

here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
python=/usr/bin/python3

missing=()
need() { command -v "$1" >/dev/null 2>&1 || missing+=("$1 (Debian package $2)"); }
need capnp capnproto
need capnpc-c++ capnproto
need lcm-gen liblcm-bin
need g++ g++
[[ -f /usr/include/capnp/generated-header-support.h ]] || missing+=("capnp headers (Debian package libcapnp-dev)")
[[ -f /usr/include/lcm/lcm_coretypes.h ]] || missing+=("lcm/lcm_coretypes.h (Debian package liblcm-dev)")
[[ -f /usr/include/msgpack.hpp ]] || missing+=("msgpack.hpp (Debian package libmsgpack-cxx-dev)")
"$python" -c 'import jinja2' 2>/dev/null || missing+=("jinja2 for $python (Debian package python3-jinja2)")
if ((${#missing[@]})); then
  echo "bench/generator: missing tools:" >&2
  printf '  %s\n' "${missing[@]}" >&2
  echo "install them with: sudo apt-get install capnproto libcapnp-dev liblcm-bin liblcm-dev libmsgpack-cxx-dev python3-jinja2 g++" >&2
  exit 1
fi

exec "$python" "$here/bench.py" --command "bench/generator/run.sh${*:+ $*}" "$@"
