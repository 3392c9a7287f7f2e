#!/usr/bin/env bash
# Makes a virtual environment with the ns-3 wheel (ns3 3.44.post0) for side-by-side benchmarks:
#   bash benchmarks/ns3_env.sh [DIR]      (default DIR: ./.ns3venv)
#   DIR/bin/python benchmarks/ns3_beacon.py --n 1000 --sim-time 100 --mode direct
# cppyy 3.5.0 ships only as source; its build must see the prebuilt cppyy-cling 6.32.8 wheel,
# or pip compiles cling from source (hours on two cores). So: cling first, then the backend
# and cppyy without build isolation, then ns3 itself. Importing ns-3 takes about 12 s.
set -euo pipefail
dir=${1:-.ns3venv}
if [ -x "$dir/bin/python" ] && "$dir/bin/python" -c "from ns import ns" >/dev/null 2>&1; then
  echo "$dir has ns-3"; exit 0
fi
rm -rf "$dir"
python3 -m venv "$dir"
"$dir/bin/pip" install -q --only-binary=:all: cppyy-cling==6.32.8
"$dir/bin/pip" install -q setuptools wheel
"$dir/bin/pip" install -q --no-build-isolation cppyy-backend==1.15.3
"$dir/bin/pip" install -q --no-build-isolation CPyCppyy==1.13.0 cppyy==3.5.0
"$dir/bin/pip" install -q --no-deps ns3==3.44.post0
"$dir/bin/python" -c "from ns import ns" >/dev/null 2>&1 && echo "$dir has ns-3"
