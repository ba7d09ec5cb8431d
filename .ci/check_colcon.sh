#!/usr/bin/env bash
# colcon keeps the ament layout that `ros2 run` needs: executables in lib/rotor_estimator/.
# Builds this checkout with a pip-installed colcon (no ROS install needed for an ament_python
# package), plain and --symlink-install, and fails when an executable is missing.
set -euo pipefail
src="$(cd "$(dirname "$0")/.." && pwd)"
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
python3 -m venv "$work/colcon"
"$work/colcon/bin/pip" install -q colcon-core colcon-python-setup-py colcon-ros colcon-package-selection
for mode in plain symlink; do
  ws="$work/ws_$mode"
  mkdir -p "$ws/src"
  git -C "$src" archive --prefix=rotor_estimator/ HEAD | tar -x -C "$ws/src"
  flag=""; [ "$mode" = symlink ] && flag="--symlink-install"
  (cd "$ws" && PATH="$work/colcon/bin:$PATH" colcon build $flag > build.log 2>&1) || { cat "$ws/build.log"; exit 1; }
  for exe in estimator_node simulator_node virtual_sensing_node rotor-estimator; do
    test -x "$ws/install/rotor_estimator/lib/rotor_estimator/$exe" || { echo "colcon ($mode): lib/rotor_estimator/$exe missing"; exit 1; }
  done
  test -f "$ws/install/rotor_estimator/share/rotor_estimator/package.xml"
  test -f "$ws/install/rotor_estimator/share/ament_index/resource_index/packages/rotor_estimator"
  echo "colcon build ($mode): ament layout OK"
done
