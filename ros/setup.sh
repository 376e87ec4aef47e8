#!/bin/sh
# The message packages no wheel carries (grid_map_msgs, tf2_msgs), generated into a
# virtualenv that has the ros extra's wheels (make ros). Usage: ros/setup.sh VENV
# Idempotent: each package is built in VENV/ros-build/NAME and installed into VENV itself,
# where the wheels' message packages are (share/, lib/, site-packages).
set -eu
VENV=$(cd "$1" && pwd)
HERE=$(cd "$(dirname "$0")" && pwd)
PY="$VENV/bin/python"
SITE=$("$PY" -c 'import sysconfig; print(sysconfig.get_paths()["purelib"])')
PYINC=$("$PY" -c 'import sysconfig; print(sysconfig.get_paths()["include"])')
NPINC=$("$PY" -c 'import numpy; print(numpy.get_include())')
# ros-wheels-bootstrapper (a dependency of the rclpy wheel) re-executes every Python process
# of the virtualenv with LD_LIBRARY_PATH set; mmstab sets it for `mmstab node` alone
"$PY" -m pip uninstall --quiet --yes ros-wheels-bootstrapper 2>/dev/null || true
# the wheels' exported CMake targets name the wheel builder's include folders: point them here
grep -l '/opt/python/' "$VENV"/share/*/cmake/*.cmake 2>/dev/null | while read -r f; do
  sed -i -e "s#/opt/python/cp[0-9]*-cp[0-9]*/include/python[0-9.]*#$PYINC#g" \
         -e "s#/opt/python/cp[0-9]*-cp[0-9]*/lib/python[0-9.]*/site-packages/numpy/_core/include#$NPINC#g" "$f"
done
LIBS=$(ls -d "$SITE"/ros_*.libs | tr '\n' ':')
for pkg in grid_map_msgs tf2_msgs; do
  build="$VENV/ros-build/$pkg"
  # a cache generated from another checkout's sources makes cmake refuse: start that one afresh
  if [ -f "$build/CMakeCache.txt" ] && ! grep -q "^CMAKE_HOME_DIRECTORY:INTERNAL=$HERE/$pkg\$" "$build/CMakeCache.txt"; then
    rm -rf "$build"
  fi
  mkdir -p "$build"
  ( cd "$build" &&
    AMENT_PREFIX_PATH="$VENV" LD_LIBRARY_PATH="$LIBS$VENV/lib" PATH="$VENV/bin:$PATH" \
      cmake "$HERE/$pkg" -DCMAKE_INSTALL_PREFIX="$VENV" -DCMAKE_PREFIX_PATH="$VENV" \
        -DPython3_EXECUTABLE="$PY" -DBUILD_TESTING=OFF -DCMAKE_BUILD_TYPE=Release >build.log 2>&1 &&
    AMENT_PREFIX_PATH="$VENV" LD_LIBRARY_PATH="$LIBS$VENV/lib" PATH="$VENV/bin:$PATH" \
      make -j2 install >>build.log 2>&1 ) || { echo "ros/setup.sh: $pkg failed, see $build/build.log" >&2; exit 1; }
done
# site-packages/<pkg> is where rclpy imports them from: check both import
"$PY" -c 'import grid_map_msgs.msg, tf2_msgs.msg' || { echo "ros/setup.sh: generated packages do not import" >&2; exit 1; }
