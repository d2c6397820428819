# Tree from Video — the two set-up commands are `make demo` and `make test`.
PY := .venv/bin/python
SAMPLE ?= broad
REAL_BLENDER := ../shared/tools/real-blender

.PHONY: setup demo lint test test-core test-blender bench clean extension extension-per-python test-extension

setup:
	bash scripts/setup.sh

demo: setup
	$(PY) batch.py sample_videos/$(SAMPLE)/video.mp4 --outline sample_videos/$(SAMPLE)/outline.json \
		--out out/$(SAMPLE) --npz --fbx --usd --gltf --blend --preview --force
	@echo "demo: wrote out/$(SAMPLE)/: skeleton.npz tree3d.npz result.npz overlay.png overlay.mp4" \
		"tree.blend tree.fbx tree.usdc tree.glb preview.png"

# ruff over the whole repository, mypy over core/ (settings in pyproject.toml); the first step of make test.
lint: setup
	$(PY) -m ruff check .
	$(PY) -m mypy

test: setup lint
	bash scripts/test.sh

test-core: setup
	$(PY) -m pytest -q tests

test-blender:
	bash scripts/test_blender.sh

# Extension zips with the scipy/OpenCV wheels, one per platform, in dist/ (wheels cached in wheels/).
# Limit with e.g. `make extension EXT_ARGS="--platform linux-x64"`.
extension: setup
	$(PY) scripts/build_extension.py $(EXT_ARGS)

# Separate zips per Blender Python (dist/cp311: Blender 4.2-5.0, dist/cp313: 5.1+): safe for Blender
# 4.2.0, whose installer may not filter wheels by Python tag.
extension-per-python: setup
	$(PY) scripts/build_extension.py --python 3.11 $(EXT_ARGS)
	$(PY) scripts/build_extension.py --python 3.13 $(EXT_ARGS)

# Build the linux-x64 zip, install it into the real Blender 4.3 and a Python 3.11 venv, reconstruct.
test-extension: setup
	bash scripts/test_extension.sh

# every benchmark in benchmarks/ (bench_*.py), one after the other (2 cores: never side by side)
# bench_forest_export.py starts background Blenders, so it runs inside the real Blender
bench: setup
	@set -e; for b in benchmarks/bench_*.py; do [ $$b = benchmarks/bench_forest_export.py ] && continue; \
		echo "== $$b"; $(PY) $$b; done
	@echo "== benchmarks/bench_forest_export.py"; $(REAL_BLENDER) run blender -b --factory-startup \
		--python benchmarks/bench_forest_export.py

clean:
	rm -rf out dist .pytest_cache
