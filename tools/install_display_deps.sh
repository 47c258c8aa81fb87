#!/usr/bin/env bash
# Installs what the presenter tests need on a machine with no monitor (Debian/Ubuntu):
# Xvfb (the virtual screen), Mesa's software OpenGL, xwd (screenshots) and xdotool (key presses).
# Does nothing when they are all there; uses sudo when not run as root.
set -euo pipefail
missing=0
for program in Xvfb xwd xdotool; do command -v "$program" >/dev/null || missing=1; done
ls /usr/lib/*/dri/swrast_dri.so /usr/lib/*/dri/llvmpipe_dri.so /usr/lib/*/dri/kms_swrast_dri.so >/dev/null 2>&1 || missing=1
[ "$missing" = 0 ] && exit 0
sudo=""
[ "$(id -u)" = 0 ] || sudo="sudo"
packages="xvfb x11-apps xdotool libgl1-mesa-dri libglx-mesa0 libegl1"
export DEBIAN_FRONTEND=noninteractive
$sudo apt-get install -y -q $packages >/dev/null || { $sudo apt-get update -q >/dev/null && $sudo apt-get install -y -q $packages >/dev/null; }
