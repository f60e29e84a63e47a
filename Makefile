# magvine: the two commands of the README quick start, and a few more.
#   make demo   installs dependencies, builds, lets the navigator steer the magnetic-fluid vine through the
#               generated bronchial tree with the EPM held by an iiwa arm beside the patient
#               (assets/scenes/bronchial_tree_platform.yaml), films its tip camera and an overview, plots it, writes
#               the EPM's field map
#   make test   installs dependencies, builds (warnings are errors), runs the whole ctest suite
# Other targets: build, minimal (core-only configuration + its tests), bench, figures, phantoms (the standard
# generated phantoms' meshes into phantoms/), format, lint (naming), clean.

BUILD    ?= build
MINIMAL  ?= build-minimal
JOBS     ?= $(shell nproc)
PYTHON   ?= /usr/bin/python3
DEMO_OUT ?= $(BUILD)/demo
CMAKE_FLAGS ?=

.PHONY: deps build demo test minimal python python-path bench figures phantoms format lint clean

deps:
	@tools/install-deps.sh

build: deps
	cmake -S . -B $(BUILD) -DCMAKE_BUILD_TYPE=Release -DMAGVINE_WERROR=ON $(CMAKE_FLAGS)
	cmake --build $(BUILD) -j $(JOBS)

test: build
	cd $(BUILD) && ctest --output-on-failure -j $(JOBS)

# The minimal configuration: no render module, no MPM, no CT import, core + magnetics + scene + cli and their tests; the hot
# kernels in their baseline x86-64 build only (the full build runs the AVX2 copies on machines that have AVX2).
minimal: deps
	cmake -S . -B $(MINIMAL) -DCMAKE_BUILD_TYPE=Release -DMAGVINE_WERROR=ON \
	      -DMAGVINE_WITH_RENDER=OFF -DMAGVINE_WITH_MPM=OFF -DMAGVINE_WITH_CT=OFF -DMAGVINE_MULTIVERSION=OFF \
	      -DMAGVINE_WITH_PYTHON=OFF $(CMAKE_FLAGS)
	cmake --build $(MINIMAL) -j $(JOBS)
	cd $(MINIMAL) && ctest --output-on-failure -j $(JOBS)

# The Python module (docs/python.md): `make python`, then PYTHONPATH=$$(make -s python-path) python3 -c 'import magvine'.
python: deps
	cmake -S . -B $(BUILD) -DCMAKE_BUILD_TYPE=Release -DMAGVINE_WERROR=ON $(CMAKE_FLAGS)
	cmake --build $(BUILD) -j $(JOBS) --target magvine_python

python-path:
	@echo $(abspath $(BUILD))/python

phantoms: build
	phantoms/generate.sh $(BUILD)/src/cli/magvine phantoms

demo: build
	$(BUILD)/src/cli/magvine run assets/scenes/bronchial_tree_platform.yaml --out $(DEMO_OUT)/bronchial_tree
	$(PYTHON) tools/plot_experiment.py $(DEMO_OUT)/bronchial_tree --out $(DEMO_OUT)/bronchial_tree.png \
	    --title "Ø5 mm magnetic-fluid vine, navigator and iiwa arm to branch 0-0-1 of the generated bronchial tree (35 kPa)"
	$(BUILD)/src/cli/magvine field-map --magnets assets/magnets/epm_n52.yaml --plane xz \
	    --extent 300 --units mm --resolution 241 --out $(DEMO_OUT)
	$(PYTHON) tools/plot_field_map.py $(DEMO_OUT)/field_map.csv --out $(DEMO_OUT)/field_map.png \
	    --title "N52 EPM, Ø101.6 × 101.6 mm, J = 1.48 T (exact cylinder)"
	@echo
	@echo "demo outputs:"
	@echo "  $(DEMO_OUT)/bronchial_tree/tip.mp4       the tip camera's view (fisheye 120°) as the vine grows"
	@echo "  $(DEMO_OUT)/bronchial_tree/overview.mp4  the run from outside: airway, vine, EPM, target, planned path"
	@echo "  $(DEMO_OUT)/bronchial_tree.png           tip path, body, magnet path, wall forces"
	@echo "  $(DEMO_OUT)/bronchial_tree/              metrics.json, tip/magnet trajectories, arms.csv, events.json, graph.json"
	@echo "  $(DEMO_OUT)/field_map.png                |B| and |grad B| of the default EPM in the xz plane"

bench: deps
	cmake -S . -B $(BUILD) -DCMAKE_BUILD_TYPE=Release -DMAGVINE_BUILD_BENCHMARKS=ON $(CMAKE_FLAGS)
	cmake --build $(BUILD) -j $(JOBS) --target bench_fields bench_mesh_import bench_contacts bench_rod bench_design bench_render bench_centerline bench_ct
	$(BUILD)/tests/bench/bench_fields --benchmark_min_time=0.5
	$(BUILD)/tests/bench/bench_mesh_import
	$(BUILD)/tests/bench/bench_contacts --benchmark_min_time=0.5
	$(BUILD)/tests/bench/bench_rod
	$(BUILD)/tests/bench/bench_design
	$(BUILD)/tests/bench/bench_render
	$(BUILD)/tests/bench/bench_centerline
	$(BUILD)/tests/bench/bench_ct

# Regenerates the README figures in docs/figures (field-model and phantom-meshing error against runtime, the robot
# mechanics validation; ~3 min).
figures: build
	$(BUILD)/src/cli/magvine study field-models --magnets assets/magnets/epm_n52.yaml --out docs/figures
	$(PYTHON) tools/plot_field_models.py docs/figures --out docs/figures/field_models.png
	$(BUILD)/src/cli/magvine study phantom-meshing --out docs/figures
	$(PYTHON) tools/plot_meshing_study.py docs/figures --out docs/figures/meshing_study.png
	$(BUILD)/src/cli/magvine study centerline --out docs/figures
	$(PYTHON) tools/plot_centerline_study.py docs/figures
	$(BUILD)/src/cli/magvine validate --out docs/figures
	$(PYTHON) tools/plot_mechanics.py docs/figures
	$(BUILD)/src/cli/magvine study design --out docs/figures
	$(BUILD)/src/cli/magvine study ct-import --out docs/figures \
	    --segmentation ../shared/airways/segmentations/Patient1/bronchialTree.nii.gz \
	    --reference ../shared/airways/lidc0297_medmpd_p1_airway_mc.stl \
	    --segmentation ../shared/airways/segmentations/Patient5/bronchialTree.nii.gz \
	    --reference ../shared/airways/lidc0525_medmpd_p5_airway_mc.stl
	$(PYTHON) tools/plot_ct_study.py docs/figures
	$(PYTHON) tools/plot_design_study.py docs/figures --out docs/figures/design_study.png
	sed 's/speed: 0.5}/speed: 0.5, frames: true}/' assets/scenes/bronchial_tree_navigator.yaml \
	    > $(BUILD)/navigator_frames.yaml
	$(BUILD)/src/cli/magvine run $(BUILD)/navigator_frames.yaml --out $(BUILD)/navigator_frames
	$(PYTHON) tools/plot_frames.py $(BUILD)/navigator_frames --camera tip --speed 0.5 --frames 0,120,240,360 \
	    --out docs/figures/tip_camera.png
	$(PYTHON) tools/plot_frames.py $(BUILD)/navigator_frames --camera overview --speed 0.5 --frames 0,190,380 \
	    --out docs/figures/overview.png
	sed 's/speed: 0.5}/speed: 0.5, frames: true}/' assets/scenes/bronchial_tree_platform.yaml \
	    > $(BUILD)/platform_frames.yaml
	$(BUILD)/src/cli/magvine run $(BUILD)/platform_frames.yaml --out $(BUILD)/platform_frames
	cp $(BUILD)/platform_frames/overview_frames/000300.png docs/figures/platform_overview.png
	$(PYTHON) tools/plot_experiment.py $(BUILD)/platform_frames --out docs/figures/demo_bronchial_tree.png \
	    --title "Ø5 mm magnetic-fluid vine, navigator and iiwa arm to branch 0-0-1 of the generated bronchial tree (35 kPa)"

format:
	find src tests -name '*.?pp' | xargs clang-format -i

lint: build
	find src -name '*.cpp' | xargs -n1 clang-tidy -p $(BUILD) --quiet

clean:
	rm -rf $(BUILD) $(MINIMAL)
