# Source this file (bash or zsh) to use the project's venv in a shell:
#   source scripts/env.sh
# Exports AMENT_PREFIX_PATH=<repo>/.venv (needed by ament_index / message look-ups) and puts
# <repo>/.venv/bin first on PATH. Run scripts/setup.sh (or `make setup`) first.
if [ -n "${BASH_SOURCE:-}" ]; then
  _pam_env_file="${BASH_SOURCE[0]}"
elif [ -n "${ZSH_VERSION:-}" ]; then
  eval '_pam_env_file="${(%):-%x}"'
else
  _pam_env_file="${0}"
fi
_pam_root="$(cd "$(dirname "$_pam_env_file")/.." && pwd)"
if [ ! -x "$_pam_root/.venv/bin/python" ]; then
  echo "env.sh: $_pam_root/.venv is missing: run scripts/setup.sh (or make setup) first" >&2
fi
export AMENT_PREFIX_PATH="$_pam_root/.venv"
case ":${PATH}:" in
  *":$_pam_root/.venv/bin:"*) ;;
  *) export PATH="$_pam_root/.venv/bin:${PATH}" ;;
esac
unset _pam_env_file _pam_root
