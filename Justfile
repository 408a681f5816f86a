# silpose tasks. Every recipe first makes sure .venv matches uv.lock (fast when it does).
set positional-arguments
set shell := ["bash", "-euo", "pipefail", "-c"]

# list the recipes
default:
    @just --list

# install everything into .venv (Python 3.11, bpy, Ray extra, dev tools); changes nothing while .venv matches
# uv.lock. Then correct bpy 5.0.1's installed WHEEL tags (cp39; its wheel file is cp311), or every later
# `uv sync` / `uv run` would reinstall bpy under running Blender workers (see silpose.shared.wheel_tags).
# --compile-bytecode: the installed packages' .pyc files are written once here, so a process that cannot write them
# (PYTHONDONTWRITEBYTECODE, a read-only .venv) does not compile scikit-learn, scipy and pandas again at every start
# (measured: `import silpose.model` 4.3 s -> 2.1 s; every spawned worker and `silpose` command pays it)
setup:
    uv sync --all-extras --frozen --compile-bytecode
    .venv/bin/python -m silpose.shared.wheel_tags

# generate a dataset: just gen [preset|config.toml] [extra silpose gen options]
gen preset="default" *args: setup
    uv run --no-sync silpose gen "{{preset}}" "${@:2}"

# fit the shape+structure model on data/<preset>/: just train [preset] [options]
train preset="default" *args: setup
    uv run --no-sync silpose train "{{preset}}" "${@:2}"

# run the paper's experiments on data/<preset>/ and models/<preset>.npz
eval preset="default" *args: setup
    uv run --no-sync silpose eval "{{preset}}" "${@:2}"

# gen -> train -> eval for one preset (the main job)
all preset="default": setup
    uv run --no-sync silpose gen {{preset}}
    uv run --no-sync silpose train {{preset}}
    uv run --no-sync silpose eval {{preset}}

# textured camera frames + empty-room frames + truth: just frames [preset|config.toml] [--samples N] [--background N] [--out DIR]
frames preset="default" *args: setup
    uv run --no-sync silpose gen-frames "{{preset}}" "${@:2}"

# check a generated dataset folder
validate dir *args: setup
    uv run --no-sync silpose validate "$@"

# run the benchmarks in benchmarks/ into reports/bench/: just bench [--quick] [--only SECTIONS] [--set S.K=V] (see --help)
bench *args: setup
    uv run --no-sync python -m benchmarks.run "$@"

# the whole test suite (what CI runs), on 2 pytest-xdist workers (the serial run took 9.7 min on 2 cores);
# `uv run pytest FILE` runs one file serially
test *args: setup
    uv run --no-sync pytest -n 2 --dist loadgroup "$@"

# docs/results.md and the README's generated tables, from reports/*/headline.json and reports/bench/bench.json
# (`just results --only bench`: the benchmark tables alone, after a `just bench` on a machine without the reports)
results *args: setup
    uv run --no-sync python docs/results.py "$@"
