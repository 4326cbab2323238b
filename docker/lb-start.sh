#!/usr/bin/env bash
# The lb image's command: renders nginx's configuration from the NGINX_* environment
# (docker/render-nginx-conf.sh), waits until every upstream name resolves, then runs nginx.
# nginx resolves upstream names once, at start, and refuses to start on a name it cannot
# resolve, which a replica not yet started is; so wait, bounded by NGINX_WAIT_SECONDS
# (default 60), and say for which name.
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
conf=${NGINX_CONF:-/etc/nginx/nginx.conf}
bash "$here/render-nginx-conf.sh" >"$conf"

wait_s=${NGINX_WAIT_SECONDS:-60}
deadline=$((SECONDS + wait_s))
for u in ${NGINX_UPSTREAMS:-hdeform-1:50051 hdeform-2:50051 hdeform-3:50051} \
         ${NGINX_HTTP_UPSTREAMS:-hdeform-1:8080 hdeform-2:8080 hdeform-3:8080}; do
  host=${u%:*}
  until getent hosts "$host" >/dev/null; do
    if [ "$SECONDS" -ge "$deadline" ]; then
      echo "lb-start: upstream $host does not resolve after ${wait_s} s; starting nginx anyway" >&2
      break
    fi
    echo "lb-start: waiting for upstream $host to resolve" >&2
    sleep 1
  done
done
nginx -t -q -c "$conf"
exec nginx -c "$conf" -g 'daemon off;'
