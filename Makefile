# The two commands the README starts with. Each installs what is missing
# (Debian packages through apt-get, then the Rust build) and runs.

.PHONY: demo test setup bench

setup:
	bash scripts/setup.sh

demo: setup
	cargo build --release --workspace --bins
	bash scripts/demo.sh

test: setup
	bash scripts/test.sh

bench: setup
	cargo bench -p relief-daemon --bench pyramid
	cargo bench -p relief-daemon --bench reload
	cargo bench -p relief-daemon --bench rasterize
	cargo bench -p relief-daemon --bench render
	cargo bench -p relief-daemon --bench frames
