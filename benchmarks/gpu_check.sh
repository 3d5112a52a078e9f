#!/usr/bin/env bash
# The checks that need a CUDA GPU, in one run: the tests that skip without one, then the model's throughput
# there (benchmarks/throughput_gpu.py). Run from the repository root on a machine with torch (CUDA build),
# torch-geometric, numpy, scipy, click, tqdm, psutil and usd-core; OUT (default ./gpu_out) gets the logs and
# the table. Where a package is missing, wheels in .whl/ are installed into /tmp/site first; for the lent H200
# (Python 3.12, no usd-core), made on a machine with network access:
#   pip download --no-deps --only-binary=:all: --python-version 3.12 --implementation cp \
#       --platform manylinux_2_28_x86_64 -d .whl usd-core==26.11
set -uo pipefail
OUT=${OUT:-gpu_out}
mkdir -p "$OUT"
if compgen -G ".whl/*.whl" >/dev/null; then
    python3 -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade --target /tmp/site .whl/*.whl \
        && export PYTHONPATH=/tmp/site${PYTHONPATH:+:$PYTHONPATH}
fi
export PYTHONPATH=$PWD${PYTHONPATH:+:$PYTHONPATH} PYTHONUNBUFFERED=1
nvidia-smi --query-gpu=name,memory.total,driver_version,clocks.sm --format=csv
python3 -c "import torch, torch_geometric, numpy; print('torch', torch.__version__, 'pyg', torch_geometric.__version__, 'numpy', numpy.__version__, 'cuda', torch.cuda.is_available())"
python3 -m pytest -q -p no:cacheprovider -rs tests/garmentcli/test_bake_model.py tests/garmentcli/test_train_cli.py tests/garmentcli/test_tradeoff_cli.py -k "device or gpu" 2>&1 | tee "$OUT/pytest.log"
python3 benchmarks/throughput_gpu.py --repeats 3 --out "$OUT/throughput_gpu.md" 2>&1 | tee "$OUT/throughput_gpu.log"
