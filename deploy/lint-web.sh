#!/usr/bin/env bash
# The web app's JavaScript (clients/web: src/, test/, build.mjs, its configs)
# by ESLint (clients/web/eslint.config.mjs: recommended rules, functions of
# at most 60 lines, pure src/lib, no page importing another) and laid out
# as clients/web/.prettierrc.json says:
#
#   deploy/lint-web.sh          changes nothing: lists the findings and the
#                               files Prettier would change; exits 1 if any
#                               (CI runs this)
#   deploy/lint-web.sh --fix    rewrites the files with Prettier and applies
#                               ESLint's fixes, then checks again
#
# Needs node and the web app's npm packages (`npm ci --prefix clients/web`,
# which deploy/setup-debian.sh runs).
set -euo pipefail
cd "$(dirname "$0")/.."

fix=0
case "${1:-}" in
  --fix) fix=1 ;;
  "") ;;
  *) sed -n '2,/^set -euo/p' "$0" | sed -e '$d' -e 's/^# \{0,1\}//' >&2; exit 2 ;;
esac
if ! command -v node >/dev/null 2>&1; then
  echo "lint-web.sh: node is not installed (apt-get install nodejs npm)" >&2
  exit 1
fi
cd clients/web
for tool in eslint prettier; do
  if [ ! -x "node_modules/.bin/$tool" ]; then
    echo "lint-web.sh: clients/web/node_modules has no $tool: run 'npm ci --prefix clients/web' first" >&2
    exit 1
  fi
done

if ((fix)); then
  node_modules/.bin/prettier --write --log-level warn .
  node_modules/.bin/eslint --fix . || true
fi
status=0
echo "lint-web.sh: eslint $(node_modules/.bin/eslint --version), prettier $(node_modules/.bin/prettier --version)"
if ! node_modules/.bin/eslint --max-warnings 0 .; then
  echo "lint-web.sh: ESLint has findings in clients/web (above)" >&2
  status=1
fi
if ! node_modules/.bin/prettier --check --log-level warn .; then
  echo "lint-web.sh: the files above are not laid out as Prettier says (deploy/lint-web.sh --fix rewrites them)" >&2
  status=1
fi
if ((status == 0)); then echo "lint-web.sh: clients/web is clean"; fi
exit "$status"
