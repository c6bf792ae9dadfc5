# The two commands the README starts with. Each installs what is missing
# (Debian packages through apt-get, then the Rust build) and runs.

.PHONY: demo test setup bench accuracy qgis-plugin

setup:
	bash scripts/setup.sh

demo: setup
	cargo build --release --workspace --bins
	bash scripts/demo.sh

test: setup
	bash scripts/test.sh

# What accuracy costs in time: every knob swept against its reference into
# docs/accuracy.md and docs/accuracy/*.svg (under 30 minutes; CI builds it,
# never runs it).
accuracy: setup
	cargo run --release -p relief-accuracy -- --out docs

# The QGIS plugin's installable zip (QGIS: Plugins > Manage and Install
# Plugins > Install from ZIP): target/qgis/relief_qgis.zip.
qgis-plugin:
	python3 clients/qgis/scripts/package.py

bench: setup
	cargo bench -p relief-engine --bench pyramid
	cargo bench -p relief-engine --bench reload
	cargo bench -p relief-engine --bench rasterize
	cargo bench -p relief-daemon --bench render
	cargo bench -p relief-daemon --bench instances
	cargo bench -p relief-daemon --bench frames
	cargo bench -p relief-daemon --bench arcgis
	cargo bench -p relief-engine --bench geopackage
	cargo bench -p relief-engine --bench bigdem
	cargo bench -p relief-daemon --bench warm
	cargo bench -p relief-daemon --bench soak
	cargo bench -p relief-daemon --bench standard_tiles
	cargo bench -p relief-tests --bench cesium_edit
	cargo bench -p relief-tests --bench objects
	bash clients/qgis/scripts/bench.sh
