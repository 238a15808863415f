#!/bin/bash
# Does the default suite catch a wrong gradient? Injects three faults into the source one at a time (issue 46's slot
# bug; the surrogate times 3; the ES group's outgoing gains cut from the gradient), runs the default-suite tests that
# should catch them, prints which fail, and restores each file from git (run it on a clean work tree):
#   bash experiments/gradient_faults.sh
set -uo pipefail
cd "$(dirname "$0")/.."
py=${PYTHON:-.venv/bin/python}
files="jaxarm/network/network.py jaxarm/network/surrogate.py jaxarm/network/synapses.py"
if ! git diff --quiet -- $files; then echo "uncommitted changes in $files: commit or stash them first"; exit 2; fi
run() {
  "$py" -m pytest -q -p no:cacheprovider tests/test_gradient_learning.py tests/test_surrogate_timing.py \
    -k "share or surrogate_is or tangent or block_delivery" 2>&1 | grep -E "^(FAILED|[0-9]+ (passed|failed))"
  git checkout -- $files
}
echo "== slot bug (a cell that did not fire sends its derivative from step 0)"
sed -i 's/jnp.where(spike_step >= 0, spike_step, near_step), value,/jnp.where(spike_step >= 0, spike_step, 0), value,/' \
  jaxarm/network/network.py
run
echo "== surrogate x3"
sed -i 's/    smooth = jnp.where(eligible, scale \* fast_sigmoid/    smooth = jnp.where(eligible, 3.0 * scale * fast_sigmoid/' \
  jaxarm/network/surrogate.py
run
echo "== the ES group's outgoing gains cut from the gradient"
"$py" - <<'PY'
p = 'jaxarm/network/synapses.py'
s = open(p).read()
a = '    w = _row(tables.out_weight, net, cell, tables_batched) * wgain.at[net[:, None], syn].get(mode="clip")'
assert a in s
open(p, 'w').write(s.replace(a, a + '\n    if value is not None and g == 0:\n        w = jax.lax.stop_gradient(w)'))
PY
run
