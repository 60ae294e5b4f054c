# Shared set-up for the test scripts (sourced, not run): installing Debian packages when missing,
# and a Node.js new enough for the browser, export and engine tests. Each function prints what it
# installs to stderr and returns non-zero when it cannot.

# apt_install PKG…: install Debian packages (with sudo when not root and sudo exists).
apt_install() {
  local sudo_cmd=""
  if [ "$(id -u)" != "0" ] && command -v sudo >/dev/null 2>&1; then sudo_cmd="sudo"; fi
  echo "setup: installing $* (apt-get)" >&2
  $sudo_cmd apt-get update && DEBIAN_FRONTEND=noninteractive $sudo_cmd apt-get install -y "$@"
}

# node_version_ok: whether `node` is ≥ 20.10 (node --test's --test-concurrency, the test files'
# APIs). Debian 12's nodejs is 18: the tests need a newer one (e.g. NodeSource's), so an old node
# is an error that says so rather than a run that fails in odd ways.
node_version_ok() {
  command -v node >/dev/null 2>&1 || return 1
  node -e 'const [a, b] = process.versions.node.split(".").map(Number); process.exit(a > 20 || (a === 20 && b >= 10) ? 0 : 1)'
}

# ensure_node: node ≥ 20.10 and npm, installing Debian's nodejs and npm when they are missing,
# and when that node is too old (Debian 12's is 18) npm's `node@22` package into
# target/node (the binary comes from the npm registry), put first on PATH.
ensure_node() {
  if ! command -v node >/dev/null 2>&1 || ! command -v npm >/dev/null 2>&1; then
    apt_install nodejs npm || return 1
  fi
  node_version_ok && return 0
  local here_root
  here_root="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
  local prefix="$here_root/target/node"
  if [ ! -x "$prefix/node_modules/.bin/node" ]; then
    echo "setup: node $(node --version) is older than 20.10: installing npm's node@22 into $prefix" >&2
    npm install --prefix "$prefix" --no-audit --no-fund node@22 >&2 || return 1
  fi
  export PATH="$prefix/node_modules/.bin:$PATH"
  if ! node_version_ok; then
    echo "setup: node $(node --version) is too old: the tests need Node.js ≥ 20.10" >&2
    return 1
  fi
}

# ensure_chromium: Debian's chromium at ${CHROMIUM:-/usr/bin/chromium}.
ensure_chromium() {
  [ -x "${CHROMIUM:-/usr/bin/chromium}" ] || apt_install chromium
}

# ensure_venv DIR: a Python venv at DIR, installing Debian's python3-venv when the standard
# library's venv cannot create one (Debian's python3 without it).
ensure_venv() {
  [ -x "$1/bin/python" ] && return 0
  python3 -m venv "$1" 2>/dev/null && return 0
  rm -rf "$1"
  apt_install python3-venv && python3 -m venv "$1"
}
