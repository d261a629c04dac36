#!/usr/bin/env bash
# Install snnkart into ./.venv (Python 3.10) and run the demo or the test suite.
#
#   bash scripts/setup.sh demo   # install, then run the main job on built-in defaults
#   bash scripts/setup.sh test   # install, then run the full test suite (what CI runs)
#
# Python 3.10 is required (lava-nc 0.10 supports only 3.10). It is looked for in this order:
# $SNNKART_PYTHON, python3.10 on PATH, pyenv's versions, uv's managed Pythons, /usr/bin.
set -euo pipefail

cd "$(dirname "$0")/.."
job="${1:-}"
case "$job" in
  demo|test) shift ;;
  *) echo "usage: bash scripts/setup.sh demo|test [extra args]" >&2; exit 2 ;;
esac

is_py310() { [ -x "$1" ] && "$1" -c 'import sys; sys.exit(sys.version_info[:2] != (3, 10))' 2>/dev/null; }

find_python() {
  local c
  for c in "${SNNKART_PYTHON:-}" "$(command -v python3.10 || true)"; do
    if [ -n "$c" ] && is_py310 "$c"; then echo "$c"; return 0; fi
  done
  if command -v pyenv >/dev/null 2>&1; then
    for c in "$(pyenv root)"/versions/3.10*/bin/python3.10; do
      if is_py310 "$c"; then echo "$c"; return 0; fi
    done
  fi
  for c in "$HOME"/.pyenv/versions/3.10*/bin/python3.10 /usr/bin/python3.10 /usr/local/bin/python3.10; do
    if is_py310 "$c"; then echo "$c"; return 0; fi
  done
  if command -v uv >/dev/null 2>&1; then
    c="$(uv python find 3.10 2>/dev/null || true)"
    if [ -n "$c" ] && is_py310 "$c"; then echo "$c"; return 0; fi
  fi
  return 1
}

if ! PY="$(find_python)"; then
  cat >&2 <<'MSG'
error: snnkart needs Python 3.10 (its Loihi simulator, lava-nc 0.10, supports only 3.10),
and none was found (looked at $SNNKART_PYTHON, python3.10 on PATH, pyenv, uv, /usr/bin).
Install one, then run this command again, for example:
  pyenv install 3.10.13                  # with pyenv
  uv python install 3.10                 # with uv
  sudo apt-get install python3.10-venv   # on Debian/Ubuntu releases that ship 3.10
or point SNNKART_PYTHON at a Python 3.10 interpreter.
MSG
  exit 1
fi

VENV=.venv
extras="${SNNKART_EXTRAS:-dev,video}"   # CI: dev,bench,ray,video,sanafe,wandb,box2d,mujoco (every optional part)
stamp="$VENV/.snnkart-installed"
want="$(cat pyproject.toml constraints.txt | sha256sum | cut -d' ' -f1) $PY [$extras]"
if ! is_py310 "$VENV/bin/python"; then
  echo "creating $VENV with $PY"
  rm -rf "$VENV"
  "$PY" -m venv "$VENV"
fi
if [ "$(cat "$stamp" 2>/dev/null)" != "$want" ]; then
  echo "installing snnkart and its dependencies into $VENV (torch is large: a few minutes on a fresh machine)"
  "$VENV/bin/python" -m pip install --quiet --upgrade pip
  # the tested versions (constraints.txt), so a fresh install reproduces the golden values
  "$VENV/bin/python" -m pip install --quiet -c constraints.txt -e ".[$extras]"
  # NeuroBench's own metric code, the independent check of the closed-loop metrics
  # (tests/test_neurobench_metrics.py): without its dependencies, which pin torchaudio and
  # tonic; its metrics need only torch, snntorch and numpy
  case ",$extras," in *,dev,*)
    "$VENV/bin/python" -m pip install --quiet --no-deps -c constraints.txt neurobench==2.3.0 ;;
  esac
  echo "$want" > "$stamp"
fi

export SDL_VIDEODRIVER="${SDL_VIDEODRIVER:-dummy}" SDL_AUDIODRIVER="${SDL_AUDIODRIVER:-dummy}"
export PYGAME_HIDE_SUPPORT_PROMPT=1
if [ "$job" = demo ]; then
  exec "$VENV/bin/snnkart" demo "$@"
else
  # two workers (pytest-xdist): this machine's two cores; SNNKART_TEST_WORKERS=0 runs in one process
  # --dist loadgroup keeps the tests of one xdist_group (the Ray tests) on one worker
  workers="${SNNKART_TEST_WORKERS:-2}"
  dist=(); [ "$workers" != 0 ] && dist=(--dist loadgroup)
  exec "$VENV/bin/python" -m pytest -n "$workers" "${dist[@]}" "$@"
fi
