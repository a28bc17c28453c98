#!/bin/sh
# The linker driver of x86_64 Linux builds (.cargo/config.toml). Every integration-test binary carries the physics
# engines, and the default BFD linker links them on one core; mold links the same objects on every core and spends a
# fraction of the time. scripts/setup.sh installs mold; a machine without it links with the compiler's default
# linker, so the build never depends on mold being there.
if command -v mold >/dev/null 2>&1; then
  exec cc -fuse-ld=mold "$@"
fi
exec cc "$@"
