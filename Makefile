# One entry point for every check. `make test` is what CI (.ci/run) runs.
SHELL := /bin/bash
VENV ?= .venv
PY := $(VENV)/bin/python
export CARGO_TERM_COLOR ?= never

DIST ?= dist
# glibc 2.17 (manylinux2014): the oldest glibc the Rust toolchain supports, so the wheel
# installs on every Linux with pip >= 19.3 (RHEL/CentOS 7 and later, Debian 8+, Ubuntu 14.04+).
MANYLINUX ?= manylinux2014

.PHONY: install build-tools wheel sdist demo test test-rust test-python test-install lint fmt browser \
	bench compare fuzz fuzz-stable clean check develop lint-rust lint-python ruff test-rust-chain \
	test-python-chain fmt-check stages

$(PY):
	python3 -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip

# maturin with zig (links against glibc 2.17 symbols on any host) and auditwheel: the
# `build` dependency group of pyproject.toml.
build-tools: $(PY)
	$(PY) -m pip install --quiet --group build

# The portable wheel (release, abi3, manylinux) and the sdist, into dist/. maturin finds zig as
# `python -m ziglang` through PATH, hence the venv first on it.
wheel: build-tools sdist
	rm -f $(DIST)/slam2world-*.whl
	env -u RUSTC_WORKSPACE_WRAPPER -u RUSTFLAGS PATH="$(abspath $(VENV))/bin:$$PATH" \
		$(PY) -m maturin build --release --zig \
		--compatibility $(MANYLINUX) --out $(DIST)

sdist: build-tools
	rm -f $(DIST)/slam2world-*.tar.gz
	$(PY) -m maturin sdist --out $(DIST)

# That wheel and every test dependency, into .venv (one release build serves the tests, the
# demo and the install check). After Rust changes: `make install` again, or
# `$(VENV)/bin/pip install -e . --no-deps --no-build-isolation` for an editable build.
install: wheel
	$(PY) -m pip install --quiet "$$(ls $(DIST)/slam2world-*.whl)[test]"
	$(PY) -m pip install --quiet --no-deps --force-reinstall $(DIST)/slam2world-*.whl

# The main job on the embedded default: simulate the paper's scene, convert, score, write outputs.
demo: install
	$(VENV)/bin/slam2world demo -o out/demo

# Two chains at once, each serial: the Rust one (fmt, every Rust test, linted as they compile) and
# the Python one (the release wheel, the Python lint, the Python tests, the install check). The
# compilers leave a core idle in each crate's serial front end, pip and pytest another (fresh
# clones: 667 and 707 s; 879-970 s with a clippy pass of its own). The Python
# tests go before the install check, whose cargo builds wait for the Rust chain's (one build
# folder, one lock) and then use its compiled dependencies. Each line says its chain.
test:
	@[ -n "$(CLIPPY_DRIVER)" ] || { echo "make test: no clippy-driver (rustup component add clippy)" >&2; exit 1; }
	@( set -o pipefail; $(MAKE) --no-print-directory test-rust-chain 2>&1 | sed -u 's/^/rust   | /' ) & \
	r=$$!; \
	( set -o pipefail; $(MAKE) --no-print-directory test-python-chain 2>&1 | sed -u 's/^/python | /' ); \
	p=$$?; wait $$r; q=$$?; \
	echo "make test: the rust chain exited $$q, the python chain $$p"; \
	[ $$p = 0 ] && [ $$q = 0 ]

test-rust-chain: fmt-check test-rust
test-python-chain: lint-python test-python test-install

# The contributor loop, after each change (CONTRIBUTING.md): fmt, clippy, the Rust unit and
# integration tests and the Python tests against a debug build installed in place, leaving out
# the slow tests (cargo `#[ignore = "slow: ..."]`, pytest `-m slow`) that `make test` runs.
# Incremental builds: a one-line change in src/ recompiles little.
check: lint-rust develop ruff
	cargo test --lib --bins --test it
	$(PY) -m pytest -q -m "not slow"

# A debug build of the Python module, installed in place into .venv with the test dependencies
# (it replaces the release wheel of `make install` until that runs again).
develop: build-tools
	$(PY) -m maturin develop --quiet --extras test

# A one-shot run keeps no incremental caches (4-5 GB that a fresh machine would never reuse).
test: export CARGO_INCREMENTAL = 0

# make test lints while it compiles instead of in a clippy pass of its own: clippy-driver wraps
# rustc for this crate's own targets (RUSTC_WORKSPACE_WRAPPER, what `cargo clippy` sets) and
# RUSTFLAGS=-Dwarnings makes every warning an error (the dependencies are compiled with
# --cap-lints allow). The test build lints the library, the binary, the tests and the benches;
# the install check's sdist build (dev profile, `python` feature) lints the bindings. So the
# dependencies are compiled once, not once more in check mode for clippy alone. The release
# wheel is compiled by rustc alone: clippy-driver turns MIR optimisations off.
CLIPPY_DRIVER := $(shell command -v clippy-driver 2>/dev/null)
test: export RUSTC_WORKSPACE_WRAPPER = $(CLIPPY_DRIVER)
test: export RUSTFLAGS = -D warnings

# Every test, the slow ones included; the benches run once each as tests. One build of every
# target first, so that cargo compiles the benches beside the tests; the benches run before the
# long integration tests, while nothing else (the install check's sdist build) holds the build
# folder's lock.
test-rust:
	cargo test --all-targets --no-run
	cargo test --bench '*'
	cargo test --lib --bins --tests -- --include-ignored

# The report-page tests open report.html in headless Chromium, from Debian's packages where
# the machine has none (as root with apt); without one they skip, saying why.
browser:
	@if ! command -v chromium >/dev/null 2>&1 && command -v apt-get >/dev/null 2>&1 && [ "$$(id -u)" = 0 ]; then \
	  { apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq chromium >/dev/null; } \
	    || echo "chromium could not be installed: the browser tests will skip" >&2; \
	fi

test-python: install browser
	$(PY) -m pytest

# The wheel and the sdist installed the way users install them (tests/install/check_install.py).
test-install: install
	$(PY) tests/install/check_install.py --dist $(DIST)

lint: lint-rust lint-python

fmt-check:
	cargo fmt --check

lint-rust: fmt-check
	# One pass: `python` turns on `cli` too, and no code is compiled only without them.
	cargo clippy --all-targets --features python -- -D warnings

lint-python: install ruff
	$(PY) -m mypy python/slam2world tests/python/typing_example.py tests/install/check_install.py
	$(PY) -m mypy.stubtest slam2world._slam2world --allowlist .mypy-stubtest-allowlist

# ruff from the test extras: after `install` or `develop` (the prerequisites order it so).
ruff:
	$(PY) -m ruff check python tests benches src/live/layout.py
	$(PY) -m ruff format --check python tests benches src/live/layout.py

fmt: $(PY)
	cargo fmt
	$(PY) -m ruff format python tests benches src/live/layout.py
	$(PY) -m ruff check --fix python tests benches src/live/layout.py

bench:
	cargo bench

# The start-up stage rule scored on SCENARIOS runs of the scenario family (seeds never used in
# development): the distributions of its errors against the truth (tests/it/stages.rs).
SCENARIOS ?= 200
stages:
	SLAM2WORLD_SCENARIOS=$(SCENARIOS) cargo test --release --test it \
		stages::the_batch_cut_scored_over_the_scenario_family -- --include-ignored --nocapture

compare: install
	$(PY) benches/compare.py

# cargo-fuzz on the MCAP decoders and reader, the ROS 1 bag reader and the .db3 reader, FUZZ_SECONDS per target (nightly + cargo-fuzz).
FUZZ_SECONDS ?= 60
fuzz:
	cd fuzz && cargo +nightly fuzz run decoders -- -max_total_time=$(FUZZ_SECONDS)
	cd fuzz && cargo +nightly fuzz run mcap_file -- -max_total_time=$(FUZZ_SECONDS)
	cd fuzz && mkdir -p corpus/ros1_bag && cargo +nightly fuzz run ros1_bag corpus/ros1_bag ../tests/data/rosbag -- -max_total_time=$(FUZZ_SECONDS)
	cd fuzz && mkdir -p corpus/ros2_db3 && cargo +nightly fuzz run ros2_db3 corpus/ros2_db3 ../tests/data/rosbag/ros2_sqlite3_none ../tests/data/rosbag/ros2_sqlite3_message -- -max_total_time=$(FUZZ_SECONDS)

# Without nightly or cargo-fuzz: the MCAP reader on seeded random mutations for
# FUZZ_STABLE_SECONDS (600 by default), each batch in a worker under a 2 GiB
# address-space limit, every case checked for panics, aborts, hangs and memory.
FUZZ_STABLE_SECONDS ?= 600
fuzz-stable:
	SLAM2WORLD_MUTATION_SECONDS=$(FUZZ_STABLE_SECONDS) cargo test --release --test it mutation::mcap_random_run_for_a_while -- --nocapture

clean:
	cargo clean
	rm -rf $(VENV) out $(DIST)
