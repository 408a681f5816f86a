# silpose tasks. Every recipe first makes sure .venv matches uv.lock (fast when it does).
set positional-arguments

# list the recipes
default:
    @just --list

# install everything into .venv (Python 3.11, bpy, Ray extra, dev tools)
setup:
    uv sync --all-extras --frozen

# generate a dataset: just gen [preset|config.toml] [extra silpose gen options]
gen preset="default" *args: setup
    uv run --frozen silpose gen "$@"

# fit the shape+structure model on data/<preset>/: just train [preset] [options]
train preset="default" *args: setup
    uv run --frozen silpose train "$@"

# run the paper's experiments on data/<preset>/ and models/<preset>.npz
eval preset="default" *args: setup
    uv run --frozen silpose eval "$@"

# gen -> train -> eval for one preset (the main job)
all preset="default": setup
    uv run --frozen silpose gen {{preset}}
    uv run --frozen silpose train {{preset}}
    uv run --frozen silpose eval {{preset}}

# check a generated dataset folder
validate dir *args: setup
    uv run --frozen silpose validate "$@"

# run every benchmark (add --quick for a one-minute version)
bench *args: setup
    uv run --frozen silpose bench "$@"

# the whole test suite (what CI runs)
test *args: setup
    uv run --frozen pytest "$@"
