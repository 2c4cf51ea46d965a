#!/usr/bin/env bash
# Checks a Kubernetes Job manifest offline, without a cluster:
#
#   scripts/check-k8s-manifest.sh FILE
#
# Every YAML document in FILE must be a batch/v1 Job that validates, strictly (an unknown field
# is an error), against the schema of Kubernetes $K8S_VERSION (default 1.30.0, the oldest
# release vagsl's Indexed Job manifests target; 1.25.0 to 1.37.0 are bundled). Exits 0 when it
# does; otherwise prints the validator's message and exits 1 (2 when the validator is missing).
#
# The validator is kubernetes-validate from PyPI (pip install kubernetes-validate==1.37.0; .ci/run
# installs it), which bundles the Kubernetes OpenAPI schemas, so no network is needed.
set -euo pipefail

K8S_VERSION="${K8S_VERSION:-1.30.0}"

if [ "$#" -ne 1 ]; then
  echo "usage: $0 FILE (a Kubernetes batch/v1 Job manifest)" >&2
  exit 2
fi
file="$1"
[ -r "$file" ] || { echo "error: cannot read $file" >&2; exit 1; }
if ! command -v kubernetes-validate >/dev/null 2>&1; then
  echo "error: kubernetes-validate is not installed (pip install kubernetes-validate==1.37.0)" >&2
  exit 2
fi

# The schema check takes any kind; this one is about Jobs, so the kind is checked first.
python3 - "$file" <<'EOF'
import sys
import yaml

path = sys.argv[1]
try:
    with open(path) as f:
        docs = [d for d in yaml.safe_load_all(f) if d is not None]
except yaml.YAMLError as e:
    sys.exit(f"error: {path} is not YAML: {e}")
if not docs:
    sys.exit(f"error: {path} holds no manifest")
for i, d in enumerate(docs, 1):
    kind = d.get("kind") if isinstance(d, dict) else None
    api = d.get("apiVersion") if isinstance(d, dict) else None
    if (api, kind) != ("batch/v1", "Job"):
        sys.exit(f"error: {path}: document {i} is {api or '?'} {kind or '?'}, not a batch/v1 Job")
EOF

kubernetes-validate --strict --quiet --kubernetes-version "$K8S_VERSION" "$file"
