# photonmarch build.  `make` builds build/photonmarch (release); `make asan` builds the
# sanitizer variant under build-asan/; `make test`, `make demo`, `make bench` do what they say.
#
# Modules (dependencies point one way): renderer/ -> sh/ -> walk/, photonmap/ (walk/ and
# photonmap/ are leaves; renderer/ also uses walk/ directly). renderer/'s folders are layers
# (docs/render-core.md, "The map"); tests/check_structure.py, run by make test, holds the code to
# both and to the file size caps.
# Each module is a static library; tests/test_<module>*.c are linked into one Criterion binary.

BUILD    ?= build
CC       ?= cc
CXX      ?= c++
SAN      ?= 0

# -Wshadow and -Wfloat-conversion (the double-to-float part of -Wconversion) find real defects
# and the code is clean under them; the rest of -Wconversion (int to size_t on validated sizes,
# counts to double) gave 107 warnings and no defect (docs/robustness.md), so it is not on.
WARN     := -Wall -Wextra -Wshadow -Wfloat-conversion
DEFS     := -D_POSIX_C_SOURCE=200809L
INCS     := -Iwalk -Iphotonmap -Ish -Irenderer -Ifuzz
ifeq ($(SAN),1)
  OPT    := -O1 -g -fno-omit-frame-pointer -fsanitize=address,undefined
else ifeq ($(SAN),tsan)
  # ThreadSanitizer build (make test-tsan, with CC=clang-14 CXX=clang++-14: LLVM's OpenMP runtime
  # with its Archer tool tells TSan about OpenMP's barriers and reductions; GCC's libgomp does not).
  OPT    := -O1 -g -fno-omit-frame-pointer -fsanitize=thread
else ifeq ($(SAN),fuzz)
  # The sanitizer build of make test and make fuzz (build-fuzz/, with CC=clang-14 CXX=clang++-14):
  # everything checked by ASan + UBSan and instrumented for libFuzzer's coverage. Only the fuzz
  # binaries link -fsanitize=fuzzer; the suite (tests/run_tests) and the command line link without
  # it: the comparison hooks fall back to the sanitizer runtime's no-op ones and the inline edge
  # counters are bumped but never read, so they run as an ASan + UBSan build with a little more
  # work per branch. One build serves both (a third full build cost make test 2.5 min).
  OPT    := -O1 -g -fno-omit-frame-pointer -fsanitize=address,undefined,fuzzer-no-link
else
  OPT    := -O2 -g -march=x86-64-v2
endif
CFLAGS   := -std=c11 $(WARN) $(OPT) $(DEFS) $(INCS) -fopenmp -MMD -MP -I/usr/include/cjson
CXXFLAGS := -std=c++17 $(WARN) $(OPT) $(INCS) -fopenmp -MMD -MP -Wno-deprecated-declarations
LDFLAGS  := $(OPT) -fopenmp
LIBS_PM  := -lflann -llz4
LIBS_RD  := -lopenvdb -ltbb -lImath -lcjson -lembree3 -lassimp -ldl
LIBS     := $(LIBS_RD) $(LIBS_PM) -lm -lpthread

WK_SRC   := $(wildcard walk/*.c)
PM_SRC   := $(wildcard photonmap/*.c)
PM_CXX   := $(wildcard photonmap/*.cpp)
SH_SRC   := $(wildcard sh/*.c)
CLI_SRC  := $(wildcard renderer/cli/*.c)
# renderer/dist/: the one module that calls MPI (OpenMPI; docs/cluster.md), linked into the
# command line only (not the library, the suite, the tools or the fuzz targets, none of which
# starts MPI). Compiler and linker flags from OpenMPI's pkg-config file (mpicc --showme says the
# same).
DIST_SRC := $(wildcard renderer/dist/*.c)
MPI_CFLAGS := $(shell pkg-config --cflags ompi-c 2>/dev/null)
MPI_LIBS   := $(shell pkg-config --libs ompi-c 2>/dev/null)
RD_SRC   := $(filter-out $(CLI_SRC) $(DIST_SRC),$(wildcard renderer/*/*.c))
# OpenImageIO is reached through a module of its own (renderer/core/image_plugin.h: Debian's
# OpenImageIO loads ~260 shared objects, 0.26-0.34 s at every program start, 0.53-0.59 s under the
# sanitizers), loaded on the first image read or write; it is not in librenderer.a. The programs
# find it through their run path: the build folder, $ORIGIN for build/photonmarch and $ORIGIN/..
# for the programs in build/*/ (RPATH_TOP, RPATH_SUB).
IMG_SRC  := renderer/core/image_oiio.cpp
LIBS_IMG := -lOpenImageIO -lOpenImageIO_Util
RD_CXX   := $(filter-out $(IMG_SRC),$(wildcard renderer/*/*.cpp))

obj = $(patsubst %.c,$(BUILD)/%.o,$(filter %.c,$(1))) $(patsubst %.cpp,$(BUILD)/%.o,$(filter %.cpp,$(1)))
WK_OBJ   := $(call obj,$(WK_SRC))
PM_OBJ   := $(call obj,$(PM_SRC) $(PM_CXX))
SH_OBJ   := $(call obj,$(SH_SRC))
RD_OBJ   := $(call obj,$(RD_SRC) $(RD_CXX))

LIB_WK   := $(BUILD)/libwalk.a
LIB_PM   := $(BUILD)/libphotonmap.a
LIB_SH   := $(BUILD)/libsh.a
LIB_RD   := $(BUILD)/librenderer.a
BIN      := $(BUILD)/photonmarch
IMG_SO   := $(BUILD)/libphotonmarch-images.so
RPATH_TOP := -Wl,-rpath,'$$ORIGIN'
RPATH_SUB := -Wl,-rpath,'$$ORIGIN/..'

TEST_WK  := $(wildcard tests/test_walk*.c)
TEST_PM  := $(wildcard tests/test_photonmap*.c)
TEST_SH  := $(wildcard tests/test_sh*.c)
TEST_RD  := $(filter-out $(TEST_WK) $(TEST_PM) $(TEST_SH),$(wildcard tests/test_*.c))
TEST_SUP := $(wildcard tests/support/*.c)
TEST_BIN := $(BUILD)/tests/run_tests
FUZZ_HARNESS := $(BUILD)/fuzz/harness.o
CRITERION_FLAGS ?= --jobs 2

BENCH_SRC := $(wildcard bench/*.c)
BENCH_BIN := $(patsubst bench/%.c,$(BUILD)/bench/%,$(BENCH_SRC))

.SECONDARY: $(patsubst bench/%.c,$(BUILD)/bench/%.o,$(BENCH_SRC))
.PHONY: all deps check-deps check-test-deps asan test test-walk test-pm test-sh test-rd demo bench clean fuzz fuzz-build test-tsan
all: $(BIN)

deps:
	@bash scripts/install-deps.sh

# Before the first compile, one header of each library the build needs (the Debian packages of
# scripts/install-deps.sh; Criterion's for the tests): on a machine without them `make` says in
# one line what to run instead of stopping at the first compiler error. `make demo`, `make test`
# and the other targets that depend on `deps` install them first and build in a sub-make, whose
# check then passes. DEPS_CHECK=0 skips it (headers elsewhere than /usr/include).
DEP_HEADERS      := flann/flann.h lz4.h OpenImageIO/imageio.h cjson/cJSON.h embree3/rtcore.h \
                    assimp/cimport.h openvdb/openvdb.h tbb/tbb.h
TEST_DEP_HEADERS := criterion/criterion.h
DEPS_CHECK       ?= 1
missing_headers = $(if $(filter 1,$(DEPS_CHECK)),$(patsubst /usr/include/%,%,$(filter-out $(wildcard $(addprefix /usr/include/,$(1))),$(addprefix /usr/include/,$(1)))))
DEPS_MISSING      := $(strip $(call missing_headers,$(DEP_HEADERS)) $(if $(filter 1,$(DEPS_CHECK)),$(if $(MPI_LIBS),,OpenMPI (pkg-config ompi-c))))
TEST_DEPS_MISSING := $(call missing_headers,$(TEST_DEP_HEADERS))
check-deps:
	$(if $(DEPS_MISSING),$(error the build needs $(DEPS_MISSING) (not in /usr/include): run 'bash scripts/install-deps.sh' first, or 'make demo' / 'make test', which run it))
check-test-deps: check-deps
	$(if $(TEST_DEPS_MISSING),$(error the tests need $(TEST_DEPS_MISSING) (not in /usr/include): run 'bash scripts/install-deps.sh' first, or 'make test', which runs it))

$(BUILD)/%.o: %.c | check-deps
	@mkdir -p $(dir $@)
	$(CC) $(CFLAGS) -c $< -o $@

$(BUILD)/%.o: %.cpp | check-deps
	@mkdir -p $(dir $@)
	$(CXX) $(CXXFLAGS) -c $< -o $@
$(call obj,$(wildcard tests/*.c) $(TEST_SUP)): | check-test-deps
$(call obj,$(DIST_SRC)): CFLAGS += $(MPI_CFLAGS)

$(LIB_WK): $(WK_OBJ)
	@mkdir -p $(dir $@)
	rm -f $@ && ar rcs $@ $^
$(LIB_PM): $(PM_OBJ)
	@mkdir -p $(dir $@)
	rm -f $@ && ar rcs $@ $^
$(LIB_SH): $(SH_OBJ)
	@mkdir -p $(dir $@)
	rm -f $@ && ar rcs $@ $^
$(LIB_RD): $(RD_OBJ)
	@mkdir -p $(dir $@)
	rm -f $@ && ar rcs $@ $^

$(call obj,$(IMG_SRC)): CXXFLAGS += -fPIC
$(IMG_SO): $(call obj,$(IMG_SRC))
	$(CXX) $(LDFLAGS) -shared $^ $(LIBS_IMG) -o $@

$(BIN): $(call obj,$(CLI_SRC) $(DIST_SRC)) $(LIB_RD) $(LIB_SH) $(LIB_WK) $(LIB_PM) | $(IMG_SO)
	$(CXX) $(LDFLAGS) $(RPATH_TOP) $^ $(LIBS) $(MPI_LIBS) -o $@

# One Criterion binary for the whole suite, so a run ends with one summary line.
$(TEST_BIN): $(call obj,$(TEST_WK) $(TEST_PM) $(TEST_SH) $(TEST_RD) $(TEST_SUP)) $(FUZZ_HARNESS) $(LIB_RD) $(LIB_SH) $(LIB_WK) $(LIB_PM) | $(IMG_SO)
	@mkdir -p $(dir $@)
	$(CXX) $(LDFLAGS) $(RPATH_SUB) $^ $(LIBS) -lcriterion -o $@
# Per-module test binaries for development (make test-walk / test-pm / test-sh / test-rd).
$(BUILD)/tests/run_wk: $(call obj,$(TEST_WK)) $(LIB_WK)
	@mkdir -p $(dir $@)
	$(CXX) $(LDFLAGS) $^ -lm -lcriterion -o $@
$(BUILD)/tests/run_pm: $(call obj,$(TEST_PM) $(TEST_SUP)) $(LIB_PM)
	@mkdir -p $(dir $@)
	$(CXX) $(LDFLAGS) $^ $(LIBS_PM) -lm -lcriterion -o $@
$(BUILD)/tests/run_sh: $(call obj,$(TEST_SH) $(TEST_SUP)) $(LIB_SH) $(LIB_WK) $(LIB_PM)
	@mkdir -p $(dir $@)
	$(CXX) $(LDFLAGS) $^ $(LIBS_PM) -lm -lcriterion -o $@
$(BUILD)/tests/run_rd: $(call obj,$(TEST_RD) $(TEST_SUP)) $(FUZZ_HARNESS) $(LIB_RD) $(LIB_SH) $(LIB_WK) $(LIB_PM) | $(IMG_SO)
	@mkdir -p $(dir $@)
	$(CXX) $(LDFLAGS) $(RPATH_SUB) $^ $(LIBS) -lcriterion -o $@

$(BUILD)/bench/%: $(BUILD)/bench/%.o $(LIB_RD) $(LIB_SH) $(LIB_WK) $(LIB_PM) | $(IMG_SO)
	@mkdir -p $(dir $@)
	$(CXX) $(LDFLAGS) $(RPATH_SUB) $^ $(LIBS) -o $@

# Tools (tools/*.c): small programs on the public headers, for the documentation's pictures
# (scripts/make-how-it-works.sh); `make tools` builds them into $(BUILD)/tools/.
TOOLS_SRC := $(wildcard tools/*.c)
TOOLS_BIN := $(patsubst tools/%.c,$(BUILD)/tools/%,$(TOOLS_SRC))
.SECONDARY: $(patsubst tools/%.c,$(BUILD)/tools/%.o,$(TOOLS_SRC))
.PHONY: tools
tools: $(TOOLS_BIN)
$(BUILD)/tools/%: $(BUILD)/tools/%.o $(LIB_SH) $(LIB_WK) $(LIB_PM)
	@mkdir -p $(dir $@)
	$(CXX) $(LDFLAGS) $^ $(LIBS_PM) -lm -o $@

asan: deps
	$(MAKE) BUILD=build-asan SAN=1 build-asan/photonmarch

# Fuzzing (docs/robustness.md): one libFuzzer target per loader, built with clang under
# build-fuzz/ with ASan + UBSan. `make fuzz` runs each for FUZZ_SECONDS (a long campaign:
# make fuzz FUZZ_SECONDS=3600); crashes land in build-fuzz/fuzz/crashes/ and fail the target;
# timeouts (FUZZ_TIMEOUT s per input, default 60) are kept there too and reported, not failed.
FUZZ_TARGETS := scene pmap guide raw vdb image
FUZZ_SECONDS ?= 10
FUZZ_TEST_SECONDS ?= 6
FUZZ_BIN     := $(patsubst %,build-fuzz/fuzz/fuzz_%,$(FUZZ_TARGETS))
$(BUILD)/fuzz/fuzz_%: $(BUILD)/fuzz/fuzz_%.o $(FUZZ_HARNESS) $(LIB_RD) $(LIB_SH) $(LIB_WK) $(LIB_PM) | $(IMG_SO)
	$(CXX) $(LDFLAGS) $(RPATH_SUB) -fsanitize=fuzzer $^ $(LIBS) -o $@
fuzz-build: deps
	+$(SAN_MAKE) $(FUZZ_BIN)
fuzz: fuzz-build
	@bash fuzz/run.sh build-fuzz $(FUZZ_SECONDS) $(FUZZ_TARGETS)

# ThreadSanitizer over the threaded parts (docs/robustness.md): the command line built with
# -fsanitize=thread renders (passes over tiles), traces photons, bakes k-NN and track-length
# guides and looks photons up from every render thread (FLANN queries), each on 4 threads.
# Criterion cannot run under TSan (its inheritable arena fails to map: Snaipe/Criterion#274),
# so the suite itself is not used. Not in `make test` (a few minutes); halt_on_error: the first
# report fails the target. tests/tsan.supp lists the suppressions, each with its reason.
TSAN_OUT := build-tsan/out
TSAN_RUN := TSAN_OPTIONS="halt_on_error=1 exitcode=66 suppressions=$(CURDIR)/tests/tsan.supp" \
            OMP_TOOL_LIBRARIES=/usr/lib/llvm-14/lib/libarcher.so build-tsan/photonmarch
TSAN_SCENE := scenes/default.json --set camera.resolution=[32,24] --set photons.count=20000 --threads 4
test-tsan: deps
	$(MAKE) BUILD=build-tsan SAN=tsan CC=clang-14 CXX=clang++-14 build-tsan/photonmarch
	rm -rf $(TSAN_OUT)
	$(TSAN_RUN) render $(TSAN_SCENE) --spp 4 -q -o $(TSAN_OUT)/delta.exr
	$(TSAN_RUN) render $(TSAN_SCENE) --spp 2 -q --method guided --no-cache -o $(TSAN_OUT)/guided.exr
	$(TSAN_RUN) render $(TSAN_SCENE) --spp 2 -q --method uniform --no-cache --set 'march.ls="photons"' -o $(TSAN_OUT)/uniform.exr
	$(TSAN_RUN) bake $(TSAN_SCENE) -q -o $(TSAN_OUT)/knn
	$(TSAN_RUN) bake $(TSAN_SCENE) -q -o $(TSAN_OUT)/track --set 'guide={"grid":"adaptive","bake":"track"}'
	@echo "test-tsan: no data race reported"

# The suite: the release build (gcc: the command line, the suite, the tools) and the sanitizer
# build (clang 14, build-fuzz/: the command line, the suite and the fuzz targets, one build for
# all three, SAN=fuzz above), built by one make so that -j2 keeps both cores busy across the two;
# then every test in one Criterion run (the malformed-scene catalogue runs against both command
# lines), then the whole suite again in the ASan + UBSan build (build-fuzz/tests/run_tests, less
# the long checks in ASAN_FILTER), then a short run of every fuzz target (two at a time, each
# FUZZ_TEST_SECONDS); all three always run, and the target fails if any does. SAN_ENV makes the
# first sanitizer finding during a test end the test process with a non-zero status, which
# Criterion reports as a failed test.
# `make asan` (gcc, build-asan/) is not part of make test; it stays the quick sanitizer build for
# development (make BUILD=build-asan SAN=1 build-asan/tests/run_tests).
# Leaks: LeakSanitizer looks for them when a process exits, and a Criterion worker has reported
# its test by then, so a leak fails no test by itself. Every sanitizer report therefore goes to a
# file in SAN_LOG (log_path), and tests/sanitizer_reports.sh fails make test when one names an
# error, printing it (its stack names the test). The leak check runs in each test's worker only
# (tests/support/lsan_workers.c; leak_check_at_exit=0 keeps it out of Criterion's runner, whose
# own blocks at exit could only be suppressed by a `leak:libcriterion.so` that would hide every
# test's leak as well: it did until issue 24). Library leaks and UBSan reports are suppressed
# first, each entry with its library, call and reason: fuzz/lsan.supp and fuzz/ubsan.supp, the
# files the fuzz targets read too. fuzz_regress/image runs apart with the slow unwinder
# (SAN_SLOW_UNWIND): OpenImageIO's PNG leak is only recognisable by a frame inside the library,
# which the fast (frame-pointer) unwinder cannot see past libstdc++; for the whole suite the slow
# one would cost minutes. Then tests/sanitizer_reports.sh --selftest runs the planted leak and
# heap overflow of tests/test_sanitizer.c and fails make test unless both are caught.
# The CLI's leaks are caught by the malformed-scene catalogue, run against build-fuzz/photonmarch
# with detect_leaks=1 and an exit code for any report (tests/support/rd_test.h, rt_run).
# allocator_may_return_null=1: an impossible allocation returns NULL as malloc does without
# ASan, so the out-of-memory paths (and their tests) run as in a release build (the allocator's
# warning it writes is not an error).
# The sanitizer run skips (ASAN_FILTER):
#  - the long statistical checks of estimators (each a convergence test whose value is its
#    answer, checked in the release run); the code they run is exercised under ASan by the
#    shorter tests of the same modules and by the fuzz targets (beam_connect's two_media_*,
#    an_interface_* and a_clear_box_*, whose code beam_connect/a_glass_ball_* and
#    surfaces/open_region_* run under ASan, and, in session 32, the four that
#    took 24-60 s each under the sanitizers, 160 s of the run's 686: a beam's equiangular
#    sample in every marcher, whose marcher side (integrators/march_equiangular.c) runs under
#    ASan in march/single_scattering_agrees_with_delta and march/guided_continues_half_* and
#    whose chord sampler (transport/equiangular.c) in
#    integrator/equiangular_samples_a_directional_beam_s_chord and select/a_directional_beam_*;
#    the strategies' mean on the default scene, by integrator/single_scattering_strategies_* and
#    white_furnace; nee+paths against delta, by march/nee_paths_counts_*; delta's two-mode
#    tiles, by select/delta_with_equiangular_*; and, in session 33, the two narrow-spot checks
#    of the equiangular sample, 42 and 22 s: the marchers', by the two march tests just named
#    (counted with uprobes: 164 and 18 equiangular samples), guided-unbiased's, by
#    guided_unbiased/equals_delta_forward_scattering_*, wrong_and_empty_guides_* and
#    select/delta_with_equiangular_* (its flights' equiangular density 1204, 668 and 266
#    times); and, in session 35, the probes' two comparisons with delta
#    (surface_images/probes_keep_* and delta_probes_keep_*), whose code, the probes of a
#    marcher and of delta with "auto"'s epochs, runs under ASan in
#    surface_images/auto_probes_where_* and the_selection_s_pilot_*), and in session 36
#    guided-unbiased's (surface_images/guided_unbiased_probes_*, 9 s in the release run), whose
#    split path is delta's trace with another flight sampler and whose probes are those above;
#    and in session 63 the default guided's image against delta's with the beams
#    (beams/the_default_guided_gives_*, 7.5 s in the release run), whose beams, passes and
#    selection run under ASan in select/the_beams_estimator_takes_tiles_* and beams/a_render_thins_*;
#  - the tests that only spawn the command line (cli/*, memory/*, stress_big/*, and compare's
#    page, error and Ctrl-C tests, compare_cli/*): in this run they would spawn the release binary again
#    (PHOTONMARCH_BIN), so under ASan they only repeat the release run; the command line itself
#    runs under ASan + UBSan in the release run's cli/malformed_scene_catalogue_under_sanitizers;
#  - structure/* (tests/check_structure.py reads the release build's objects with nm; run once);
#  - mpi/* (tests/test_mpi.c): they only spawn mpirun and the release command line (nothing of
#    the suite's own code is under test there), and so no process of the sanitizer run starts
#    MPI: OpenMPI's start-up leaves blocks LeakSanitizer would report, which are none of ours.
# Together they would take the suite past 15 minutes.
SAN_BUILD := build-fuzz
SAN_MAKE  := $(MAKE) BUILD=$(SAN_BUILD) SAN=fuzz CC=clang-14 CXX=clang++-14
ASAN_FILTER := '!(fuzz_regress/image|render/pixels_of_one_image_are_uncorrelated|guided_unbiased/each_part_alone_*|guided_unbiased/flight_sampler_chi_square_*|march/guided_and_transmittance_share_*|march/defensive_only_and_wrong_guides_*|photons/knn_radiance_converges_*|integrator/white_furnace_every_tracker|stress_big/*|cli/*|memory/*|compare/page_loads_*|compare/bad_reference_*|compare/ctrl_c_*|compare_cli/*|geom/cli_renders_shapes|structure/*|progressive/squared_gap_*|mpi/*|beam_connect/forward_scattering_*|beam_connect/guided_unbiased_s_*|beam_connect/a_second_light_*|beam_connect/two_media_*|beam_connect/an_interface_*|beam_connect/a_clear_box_*|march/a_directional_beam_s_equiangular_*|integrator/strategies_keep_the_mean_on_the_default_scene|march/nee_paths_marchers_equal_delta_*|select/delta_s_own_tiles_mix_*|select/guided_unbiased_paths_in_*|march/equiangular_sample_keeps_*|guided_unbiased/equiangular_strategy_keeps_*|surface_images/probes_keep_*|surface_images/delta_probes_keep_*|surface_images/guided_unbiased_probes_*|beams/the_default_guided_gives_*)'
SAN_LOG := $(SAN_BUILD)/sanitizer-reports
SAN_ASAN := halt_on_error=1:detect_leaks=1:leak_check_at_exit=0:allocator_may_return_null=1:log_path=$(CURDIR)/$(SAN_LOG)/process
SAN_ENV := ASAN_OPTIONS=$(SAN_ASAN) \
           UBSAN_OPTIONS=halt_on_error=1:print_stacktrace=1:suppressions=$(CURDIR)/fuzz/ubsan.supp:log_path=$(CURDIR)/$(SAN_LOG)/process \
           LSAN_OPTIONS=suppressions=$(CURDIR)/fuzz/lsan.supp:print_suppressions=0
SAN_SLOW_UNWIND := ASAN_OPTIONS=$(SAN_ASAN):fast_unwind_on_malloc=0
# Scheduling within -j2 (make test's MAKEFLAGS): a recursive make can only take a second job slot
# when its parent frees one, so the two builds are not simply two sub-makes side by side (the one
# that ends first would leave its core idle). renderer/media/vdb_io.cpp (OpenVDB's templates) is
# the longest compile by far (about 110 s of CPU under clang's sanitizers, 60 s at -O2): the
# sanitizer build's C++ shims start at once on one core while the release build runs on the other
# (taking both once the shims are done: it is listed first, so it runs in this make's own slot and
# the shims' slot goes back to the shared pool); then the rest of the sanitizer build has both.
CXX_OBJ := $(call obj,$(filter renderer/media/vdb_io.cpp,$(RD_CXX)) $(filter-out renderer/media/vdb_io.cpp,$(RD_CXX)) $(PM_CXX))
.PHONY: test-build test-build-release test-build-san test-build-san-shims
test-build: test-build-san
test-build-san-shims:
	+$(SAN_MAKE) $(patsubst $(BUILD)/%,$(SAN_BUILD)/%,$(CXX_OBJ))
test-build-release:
	$(MAKE) $(CXX_OBJ) $(BIN) $(TEST_BIN) $(TOOLS_BIN)
test-build-san: test-build-release test-build-san-shims
	+$(SAN_MAKE) $(SAN_BUILD)/photonmarch $(SAN_BUILD)/tests/run_tests $(FUZZ_BIN)
test: deps
	$(MAKE) test-build
	@status=0; \
	echo "== release suite ($$(date +%T))"; \
	PHOTONMARCH_BIN=$(BIN) PHOTONMARCH_ASAN_BIN=$(SAN_BUILD)/photonmarch $(TEST_BIN) $(CRITERION_FLAGS) || status=1; \
	echo "== sanitizer suite (ASan + UBSan, clang) ($$(date +%T))"; \
	rm -rf $(SAN_LOG) && mkdir -p $(SAN_LOG); \
	$(SAN_ENV) PHOTONMARCH_BIN=$(BIN) $(SAN_BUILD)/tests/run_tests $(CRITERION_FLAGS) --filter $(ASAN_FILTER) || status=1; \
	$(SAN_ENV) $(SAN_SLOW_UNWIND) $(SAN_BUILD)/tests/run_tests $(CRITERION_FLAGS) --filter 'fuzz_regress/image' || status=1; \
	bash tests/sanitizer_reports.sh $(SAN_LOG) || status=1; \
	$(SAN_ENV) bash tests/sanitizer_reports.sh --selftest $(SAN_BUILD)/sanitizer-selftest $(SAN_BUILD)/tests/run_tests || status=1; \
	echo "== fuzz, short ($(FUZZ_TEST_SECONDS) s per target, fixed seed; make fuzz for longer) ($$(date +%T))"; \
	FUZZ_FRESH=1 bash fuzz/run.sh $(SAN_BUILD) $(FUZZ_TEST_SECONDS) $(FUZZ_TARGETS) || status=1; \
	echo "== done ($$(date +%T))"; exit $$status

# Each installs the dependencies, then builds in a sub-make (so the build starts after them).
test-walk: deps
	$(MAKE) $(BUILD)/tests/run_wk
	$(BUILD)/tests/run_wk $(CRITERION_FLAGS)
test-pm: deps
	$(MAKE) $(BUILD)/tests/run_pm
	$(BUILD)/tests/run_pm $(CRITERION_FLAGS)
test-sh: deps
	$(MAKE) $(BUILD)/tests/run_sh
	$(BUILD)/tests/run_sh $(CRITERION_FLAGS)
test-rd: deps
	$(MAKE) $(BIN) $(BUILD)/tests/run_rd
	PHOTONMARCH_BIN=$(BIN) $(BUILD)/tests/run_rd $(CRITERION_FLAGS)

demo: deps
	$(MAKE) $(BIN)
	@bash scripts/demo.sh $(BIN)

bench: deps
	$(MAKE) $(BIN) $(BENCH_BIN)
	@bash bench/run.sh $(BUILD)

clean:
	rm -rf build build-asan build-fuzz build-tsan

-include $(shell find build build-asan build-fuzz build-tsan -name '*.d' 2>/dev/null)
