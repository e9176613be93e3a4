#!/usr/bin/env bash
# install_test.sh BUILD_DIR: `cmake --install` into a scratch prefix lays out what a cabinet PC
# needs (docs/deploying.md, "Deploy to a cabinet PC"), and the systemd unit it writes is valid,
# names the installed program and carries the real-time settings.
set -euo pipefail
build=$1
prefix=$(mktemp -d)/usr
trap 'rm -rf "$(dirname "$prefix")"' EXIT
fail() { echo "install_test: FAIL: $*" >&2; exit 1; }

cmake --install "$build" --prefix "$prefix" >/dev/null
for f in bin/zerog-rt bin/zerog bin/zerog-emu share/zerog/zerog-rt.sample.toml \
         share/zerog/make_report.py share/zerog/interactive_report.py \
         share/zerog/proto/rt_config.md share/zerog/proto/rsi.md lib/systemd/system/zerog-rt.service \
         share/zerog/kuka/zerog_rsi_ethernet.xml share/zerog/kuka/zerog_rsi.rsi.xml \
         share/zerog/kuka/README.md; do
  [ -e "$prefix/$f" ] || fail "cmake --install did not install $f"
done
"$prefix/bin/zerog-rt" --help >/dev/null || fail "the installed zerog-rt does not run"

unit=$prefix/lib/systemd/system/zerog-rt.service
grep -q "^ExecStart=$prefix/bin/zerog-rt --config /etc/zerog/zerog-rt.toml" "$unit" ||
  fail "ExecStart does not name the installed zerog-rt: $(grep ExecStart= "$unit")"
grep -q "^ExecStartPre=$prefix/bin/zerog-rt --config /etc/zerog/zerog-rt.toml --check-config" "$unit" ||
  fail "ExecStartPre does not check the configuration"
for setting in LimitRTPRIO=99 LimitMEMLOCK=infinity Restart=on-failure RestartPreventExitStatus=2 \
               StandardOutput=journal StateDirectory=zerog; do
  grep -qx "$setting" "$unit" || fail "the unit lacks $setting"
done
grep -q '@' "$unit" && fail "unsubstituted @VARIABLE@ in the unit: $(grep '@' "$unit")"
if command -v systemd-analyze >/dev/null; then
  # Offline check of every section and key, and that the programs exist and are executable.
  out=$(systemd-analyze verify "$unit" 2>&1) || fail "systemd-analyze verify: $out"
  [ -z "$out" ] || fail "systemd-analyze verify warns: $out"
else
  fail "systemd-analyze is missing (scripts/install-deps.sh installs systemd)"
fi
echo "install_test: ok ($prefix)"
