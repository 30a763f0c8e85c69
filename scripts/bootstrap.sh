# Shared by ./run and ./test: make sure .venv exists and holds the package with the given extras.
# Sourced, not executed. A second call with unchanged setup.cfg/pyproject.toml installs nothing.
set -euo pipefail

atemr_root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
atemr_venv="$atemr_root/.venv"

atemr_find_python() {
    local candidate
    for candidate in "${ATEMR_PYTHON:-}" python3.11 python3 python; do
        [ -n "$candidate" ] || continue
        if command -v "$candidate" >/dev/null 2>&1 &&
            "$candidate" -c 'import sys; sys.exit(0 if sys.version_info >= (3, 11) else 1)' 2>/dev/null; then
            command -v "$candidate"
            return 0
        fi
    done
    echo "ATEMR needs Python 3.11 or newer on PATH (or set ATEMR_PYTHON)." >&2
    return 1
}

# atemr_bootstrap EXTRAS: EXTRAS is "" for the bare runtime, "webrtc" for ./run, or "test".
atemr_bootstrap() {
    local extras="$1" spec stamp want
    if [ ! -x "$atemr_venv/bin/python" ]; then
        echo "Creating $atemr_venv ..." >&2
        "$(atemr_find_python)" -m venv "$atemr_venv"
    fi
    want="$(cat "$atemr_root/setup.cfg" "$atemr_root/pyproject.toml" | sha256sum | cut -c1-16)"
    stamp="$atemr_venv/.atemr-installed${extras:+-$extras}"
    if [ -f "$stamp" ] && [ "$(cat "$stamp")" = "$want" ]; then
        return 0
    fi
    # The test install includes everything the runtime and its webrtc extra need.
    if { [ -z "$extras" ] || [ "$extras" = "webrtc" ]; } && [ -f "$atemr_venv/.atemr-installed-test" ] &&
        [ "$(cat "$atemr_venv/.atemr-installed-test")" = "$want" ]; then
        return 0
    fi
    spec="$atemr_root"
    [ -n "$extras" ] && spec="$atemr_root[$extras]"
    echo "Installing ATEMR${extras:+ with [$extras]} into $atemr_venv ..." >&2
    "$atemr_venv/bin/python" -m pip install --quiet --disable-pip-version-check --upgrade pip setuptools wheel >&2
    "$atemr_venv/bin/python" -m pip install --quiet --disable-pip-version-check -e "$spec" >&2
    if [ "$extras" = "test" ]; then
        # pyfuzzylite (the reference the fuzzy tests compare against) pins numpy<2 although it runs on numpy 2
        # (tests/skills/fuzzy/test_against_pyfuzzylite.py proves it): with its pin the whole test environment
        # would sit on numpy 1.x, unlike what ./run installs. So it comes without its dependencies.
        "$atemr_venv/bin/python" -m pip install --quiet --disable-pip-version-check --no-deps \
            'pyfuzzylite>=8.0' >&2
    fi
    echo "$want" >"$stamp"
}
