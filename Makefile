# One entry point for every check. `make test` is what CI (.ci/run) runs.
SHELL := /bin/bash
VENV ?= .venv
PY := $(VENV)/bin/python
export CARGO_TERM_COLOR ?= never

.PHONY: install demo test test-rust test-python lint fmt bench compare fuzz fuzz-stable clean

$(PY):
	python3 -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip

# The wheel (release build) and every test dependency, into .venv.
install: $(PY)
	$(PY) -m pip install --quiet -e '.[test]'

# The main job on the embedded default: simulate the paper's scene, convert, score, write outputs.
demo: install
	$(VENV)/bin/slam2world demo -o out/demo

test: lint test-rust test-python

test-rust:
	cargo test --all-targets

test-python: install
	$(PY) -m pytest

lint: install
	cargo fmt --check
	cargo clippy --all-targets -- -D warnings
	cargo clippy --all-targets --features python -- -D warnings
	$(PY) -m ruff check python tests benches
	$(PY) -m ruff format --check python tests benches
	$(PY) -m mypy python/slam2world tests/python/typing_example.py
	$(PY) -m mypy.stubtest slam2world._slam2world --allowlist .mypy-stubtest-allowlist

fmt: $(PY)
	cargo fmt
	$(PY) -m ruff format python tests benches
	$(PY) -m ruff check --fix python tests benches

bench:
	cargo bench

compare: install
	$(PY) benches/compare.py

# cargo-fuzz on the MCAP decoders and reader and the ROS 1 bag reader, FUZZ_SECONDS per target (nightly + cargo-fuzz).
FUZZ_SECONDS ?= 60
fuzz:
	cd fuzz && cargo +nightly fuzz run decoders -- -max_total_time=$(FUZZ_SECONDS)
	cd fuzz && cargo +nightly fuzz run mcap_file -- -max_total_time=$(FUZZ_SECONDS)
	cd fuzz && mkdir -p corpus/ros1_bag && cargo +nightly fuzz run ros1_bag corpus/ros1_bag ../tests/data/rosbag -- -max_total_time=$(FUZZ_SECONDS)

# Without nightly or cargo-fuzz: the MCAP reader on seeded random mutations for
# FUZZ_STABLE_SECONDS (600 by default), each batch in a worker under a 2 GiB
# address-space limit, every case checked for panics, aborts, hangs and memory.
FUZZ_STABLE_SECONDS ?= 600
fuzz-stable:
	SLAM2WORLD_MUTATION_SECONDS=$(FUZZ_STABLE_SECONDS) cargo test --release --test mutation mcap_random_run_for_a_while -- --nocapture

clean:
	cargo clean
	rm -rf $(VENV) out
