# voxdag - plain Makefile, the one build system.
#
#   make                      build every executable into out/bin/
#   make run                  run config/default.yaml (bundled bunny; deps first)
#   make PIPELINE=config/x.yaml   run a pipeline; rerun after a crash resumes
#   make test                 every test, unit tests under ASan+UBSan too
#   make bench                benchmarks on ../shared/data (skipped if absent)
#   make config=sanitize      the same build with AddressSanitizer and UBSan
#   make deps                 install the Debian packages the build needs
#   make install PREFIX=/usr/local   tools, libvoxdag (.a, .so), headers,
#                             voxdag.pc; DESTDIR honoured; make uninstall
#
# Layout: stages/lib/ and its folders by concern (io/, voxel/, dag/, encode/,
# render/, ...) are libvoxdag; every other stages/<name>/main.c is one
# executable; tests/unit/test_*.c are unit test programs.

config ?= release
O ?= out

CC  ?= cc
CXX ?= g++
ifeq ($(CC),cc)
CC := gcc
endif

WARN     := -Wall -Wextra -Werror -Wshadow -Wstrict-prototypes -Wno-unused-parameter
CPPFLAGS += -D_GNU_SOURCE -Istages/lib
CFLAGS   += -std=c11 $(WARN) -g
CXXFLAGS += -std=c++17 -Wall -Wextra -Werror -g
LDFLAGS  += -Wl,--as-needed
LDLIBS   += -lopenvdb -lImath -ltbb -lzstd -lxxhash -lpng -ljpeg -lstb -ljansson -lm -lpthread

ifeq ($(config),release)
OUT := $(O)
CFLAGS   += -O2
CXXFLAGS += -O2
else ifeq ($(config),sanitize)
OUT := $(O)/sanitize
SAN := -fsanitize=address,undefined -fno-omit-frame-pointer -fno-sanitize-recover=undefined
CFLAGS   += -O1 $(SAN)
CXXFLAGS += -O1 $(SAN)
LDFLAGS  += $(SAN)
else ifeq ($(config),nofsync)
# make bench's price of durability only: release, every fsync skipped
# (io/publish.c, vd_sync_fd). Never for real runs: a power cut can then
# leave empty outputs behind keys.
OUT := $(O)/nofsync
CPPFLAGS += -DVD_NO_FSYNC
CFLAGS   += -O2
CXXFLAGS += -O2
else
$(error unknown config '$(config)': use release, sanitize or nofsync)
endif

# The Debian packages the build and the tests need (checked by `make deps`).
# libboost-dev: OpenVDB 10's headers include Boost, which Debian's
# libopenvdb-dev does not pull in; libopenvdb-tools: vdb_print for the tests.
# slurm-wlm, munge: the one-node Slurm that tests/cli/slurm.sh starts.
# libpng-dev, libjpeg62-turbo-dev, libstb-dev: mesh textures (PNG, JPEG,
# and stb_image for TGA, BMP and the rest); netpbm: pnmtosgi, the SGI
# encoder the SGI decoder's test checks against.
# libassimp-dev: glTF, FBX, Collada and 3DS input (voxelize-assimp);
# assimp-utils: `assimp export`, which tests/cli/assimp.sh uses to write
# the test scene again with another glTF writer than ours.
# pkg-config: tests/cli/install.sh builds examples/ as a user would.
# libmicrohttpd-dev: `voxdag view`'s HTTP server (pipeline/view.c);
# chromium, nodejs, npm, curl: the viewer's tests (tests/cli/viewer.sh,
# tests/viewer/), which drive Debian's chromium headless with
# puppeteer-core from npm (no browser of npm's own is downloaded). npm
# counts as there when its command is: NodeSource's nodejs carries its own
# npm, and Debian's npm package conflicts with that nodejs.
DEB_PACKAGES := gcc g++ make libzstd-dev libxxhash-dev libtbb-dev libyaml-dev mcl \
                libpng-dev time libopenvdb-dev libboost-dev libopenvdb-tools \
                slurm-wlm munge clang libjansson-dev python3-numpy python3-scipy \
                libjpeg62-turbo-dev libstb-dev netpbm libassimp-dev assimp-utils \
                pkg-config libmicrohttpd-dev chromium nodejs npm curl

LIB_C    := $(wildcard stages/lib/*.c stages/lib/*/*.c stages/lib/*/*/*.c)
LIB_CC   := $(wildcard stages/lib/*.cc stages/lib/*/*.cc stages/lib/*/*/*.cc)
LIB_OBJ  := $(LIB_C:stages/lib/%.c=$(OUT)/obj/lib/%.o) \
            $(LIB_CC:stages/lib/%.cc=$(OUT)/obj/lib/%.o)
LIB      := $(OUT)/lib/libvoxdag.a
TOOLS    := $(patsubst stages/%/main.c,%,$(wildcard stages/*/main.c))
BINS     := $(TOOLS:%=$(OUT)/bin/%)
RUNNER_OBJ := $(patsubst pipeline/%.c,$(OUT)/obj/pipeline/%.o,$(wildcard pipeline/*.c))
TEST_SRC := $(wildcard tests/unit/test_*.c)
TESTS    := $(TEST_SRC:tests/unit/%.c=$(OUT)/tests/%)
HEADERS  := $(wildcard stages/lib/*.h stages/lib/*/*.h stages/lib/*/*/*.h) $(wildcard tests/unit/*.h)
# Every executable `all` builds (and `make install` copies).
ALL_BINS := $(BINS) $(OUT)/bin/voxdag $(OUT)/bin/voxdag-spawn \
            $(OUT)/bin/voxelize-vdb $(OUT)/bin/voxelize-assimp

.PHONY: all run pipeline test test-build test-build-release viewer-test-deps \
	test-build-sanitize bench deps clean tests fuzz fuzz-build lib install \
	uninstall
.DEFAULT_GOAL := all

all: $(ALL_BINS)
tests: $(TESTS)

$(OUT)/obj/lib/%.o: stages/lib/%.c $(HEADERS)
	@mkdir -p $(@D)
	$(CC) $(CPPFLAGS) $(CFLAGS) -c -o $@ $<

$(OUT)/obj/lib/%.o: stages/lib/%.cc $(HEADERS)
	@mkdir -p $(@D)
	$(CXX) $(CPPFLAGS) $(CXXFLAGS) -c -o $@ $<

$(LIB): $(LIB_OBJ)
	@mkdir -p $(@D)
	rm -f $@ && ar rcs $@ $^

# The shared library, for programs outside this tree (`make install`,
# examples/). Its objects are compiled again with -fPIC into obj-pic/:
# the tools keep linking the non-PIC archive, so their speed and their
# output bytes do not depend on the shared library existing. The version
# is the headers' VD_VERSION_STRING (voxdag.h, or whichever vd_*.h holds
# it once voxdag.h is split), read here so it is written once; the soname
# carries the major number. It links what every io/ reader needs,
# libassimp too (the archive leaves io/assimp.cc out of programs that do
# not call it; a shared library has no such choice).
LIB_VERSION := $(firstword $(shell sed -n 's/^.define VD_VERSION_STRING "\(.*\)"/\1/p' \
                 stages/lib/voxdag.h $(wildcard stages/lib/vd_*.h)))
SOMAJOR     := $(firstword $(subst ., ,$(LIB_VERSION)))
ifeq ($(SOMAJOR),)
$(error no VD_VERSION_STRING "X.Y.Z" in stages/lib/voxdag.h or vd_*.h)
endif
SONAME      := libvoxdag.so.$(SOMAJOR)
SHLIB       := $(OUT)/lib/libvoxdag.so.$(LIB_VERSION)
LIB_LIBS    := -lassimp $(LDLIBS)
PIC_OBJ     := $(LIB_OBJ:$(OUT)/obj/lib/%=$(OUT)/obj-pic/lib/%)

$(OUT)/obj-pic/lib/%.o: stages/lib/%.c $(HEADERS)
	@mkdir -p $(@D)
	$(CC) $(CPPFLAGS) $(CFLAGS) -fPIC -c -o $@ $<

$(OUT)/obj-pic/lib/%.o: stages/lib/%.cc $(HEADERS)
	@mkdir -p $(@D)
	$(CXX) $(CPPFLAGS) $(CXXFLAGS) -fPIC -c -o $@ $<

$(SHLIB): $(PIC_OBJ)
	@mkdir -p $(@D)
	$(CXX) -shared -Wl,-soname,$(SONAME) $(LDFLAGS) -o $@ $^ $(LIB_LIBS)

lib: $(LIB) $(SHLIB)

$(OUT)/obj/%/main.o: stages/%/main.c $(HEADERS)
	@mkdir -p $(@D)
	$(CC) $(CPPFLAGS) $(CFLAGS) -c -o $@ $<

# voxelize hands .vdb input to voxelize-vdb, the same main.c built with
# OpenVDB, so mesh runs do not carry OpenVDB's ~30 MB (--as-needed keeps
# every other program free of it too).
$(OUT)/obj/voxelize/main-vdb.o: stages/voxelize/main.c $(HEADERS)
	@mkdir -p $(@D)
	$(CC) $(CPPFLAGS) $(CFLAGS) -DVOXELIZE_WITH_VDB -c -o $@ $<

$(OUT)/bin/voxelize-vdb: $(OUT)/obj/voxelize/main-vdb.o $(LIB)
	@mkdir -p $(@D)
	$(CXX) $(LDFLAGS) -o $@ $< $(LIB) $(LDLIBS)

# Likewise voxelize-assimp for glTF, FBX, Collada and 3DS: Assimp costs
# ~4 MB at start. Only its main references io/assimp.cc (vd_assimp_import),
# so no other program pulls that object out of the archive or links
# libassimp.
$(OUT)/obj/voxelize/main-assimp.o: stages/voxelize/main.c $(HEADERS)
	@mkdir -p $(@D)
	$(CC) $(CPPFLAGS) $(CFLAGS) -DVOXELIZE_WITH_ASSIMP -c -o $@ $<

$(OUT)/bin/voxelize-assimp: $(OUT)/obj/voxelize/main-assimp.o $(LIB)
	@mkdir -p $(@D)
	$(CXX) $(LDFLAGS) -o $@ $< $(LIB) -lassimp $(LDLIBS)

# Linked with the C++ driver because TBB's runtime is C++.
$(OUT)/bin/%: $(OUT)/obj/%/main.o $(LIB)
	@mkdir -p $(@D)
	$(CXX) $(LDFLAGS) -o $@ $< $(LIB) $(LDLIBS)

# Paths in the runner are bounded when the config is read; GCC cannot see
# that across its many path buffers.
$(OUT)/obj/pipeline/%.o: pipeline/%.c pipeline/pipeline.h $(HEADERS)
	@mkdir -p $(@D)
	$(CC) $(CPPFLAGS) $(CFLAGS) -Wno-format-truncation -c -o $@ $<

# The runner: pipeline/*.c over the library, with libyaml.
$(OUT)/bin/voxdag: $(RUNNER_OBJ) $(LIB)
	@mkdir -p $(@D)
	$(CXX) $(LDFLAGS) -o $@ $(RUNNER_OBJ) $(LIB) -lyaml -ljansson -lmicrohttpd $(LDLIBS)

# The runner's job launcher (pipeline/spawn/spawn.c says why): static and
# libc only, so it is small; no sanitizers, which would make it large and
# would only watch forks and waits.
$(OUT)/bin/voxdag-spawn: pipeline/spawn/spawn.c pipeline/spawn/spawn.h
	@mkdir -p $(@D)
	$(CC) $(CPPFLAGS) -std=c11 $(WARN) -O2 -static -o $@ $<

# benchmark helpers (tests/bench/*.c that use the library)
$(OUT)/bench/%: tests/bench/%.c $(LIB) $(HEADERS)
	@mkdir -p $(@D)
	$(CC) $(CPPFLAGS) $(CFLAGS) -c -o $@.o $<
	$(CXX) $(LDFLAGS) -o $@ $@.o $(LIB) $(LDLIBS)

$(OUT)/tests/%: tests/unit/%.c $(LIB) $(HEADERS)
	@mkdir -p $(@D)
	$(CC) $(CPPFLAGS) -Itests/unit $(CFLAGS) -UNDEBUG -c -o $@.o $<
	$(CXX) $(LDFLAGS) -o $@ $@.o $(TEST_OBJ) $(LIB) $(LDLIBS)

# The power-cut test's tool (tests/cli/powercut.sh): no library.
$(OUT)/tests/fs_shutdown: tests/tools/fs_shutdown.c
	@mkdir -p $(@D)
	$(CC) $(CPPFLAGS) $(CFLAGS) -o $@ $<

# The Assimp importer's test calls vd_assimp_import itself.
$(OUT)/tests/test_assimp: LDLIBS += -lassimp

# The planner's test calls the runner's own code (plan_expand, job_key,
# config_load): every runner object but its main(), before the library
# they call, with libyaml (libjansson is in LDLIBS already).
TEST_PLAN_OBJ := $(filter-out $(OUT)/obj/pipeline/main.o,$(RUNNER_OBJ))
$(OUT)/tests/test_plan: $(TEST_PLAN_OBJ) pipeline/pipeline.h
$(OUT)/tests/test_plan: TEST_OBJ := $(TEST_PLAN_OBJ)
$(OUT)/tests/test_plan: CPPFLAGS += -Ipipeline
$(OUT)/tests/test_plan: LDLIBS += -lyaml -lmicrohttpd

# Installs missing Debian packages; silent when everything is there.
deps:
	@missing=$$(for p in $(DEB_PACKAGES); do \
		case $$p in npm) command -v npm >/dev/null && continue ;; esac; \
		dpkg -s $$p >/dev/null 2>&1 || echo $$p; done); \
	if [ -n "$$missing" ]; then \
		echo "make deps: installing" $$missing; \
		sudo=; [ "$$(id -u)" = 0 ] || sudo=sudo; \
		$$sudo apt-get update -qq && \
		DEBIAN_FRONTEND=noninteractive $$sudo apt-get install -y -qq $$missing >/dev/null || \
		{ echo "make deps: apt-get failed; install by hand:" $$missing >&2; exit 1; }; \
	fi

# `make install PREFIX=/usr/local` (DESTDIR honoured, as packagers expect):
# the tools, libvoxdag.a, libvoxdag.so.X.Y.Z with its soname and
# development links, the viewer's page under share/voxdag/viewer/ (where
# `voxdag view` looks beside bin/), the public headers under include/voxdag/ (voxdag.h
# and the per-concern vd_*.h it includes, globbed so a new one needs no
# change here) and voxdag.pc from stages/lib/voxdag.pc.in. Libs.private
# lists what the shared library links, plus -lstdc++ for the C++ parts,
# for `pkg-config --static`. Only copies when `make test` (test-build)
# built everything already.
PREFIX ?= /usr/local
bindir ?= $(PREFIX)/bin
libdir ?= $(PREFIX)/lib
includedir ?= $(PREFIX)/include
pkgconfigdir ?= $(libdir)/pkgconfig
datadir ?= $(PREFIX)/share
PUBLIC_HEADERS := stages/lib/voxdag.h $(wildcard stages/lib/vd_*.h)
# A directory under PREFIX as ${prefix}/..., so `pkg-config
# --define-prefix` can relocate the tree.
pc_dir = $(patsubst $(PREFIX)/%,$${prefix}/%,$(1))

install: all lib
	install -d $(DESTDIR)$(bindir) $(DESTDIR)$(libdir) \
		$(DESTDIR)$(includedir)/voxdag $(DESTDIR)$(pkgconfigdir)
	install -m 755 $(ALL_BINS) $(DESTDIR)$(bindir)/
	install -m 644 $(LIB) $(DESTDIR)$(libdir)/
	install -m 755 $(SHLIB) $(DESTDIR)$(libdir)/
	ln -sf $(notdir $(SHLIB)) $(DESTDIR)$(libdir)/$(SONAME)
	ln -sf $(SONAME) $(DESTDIR)$(libdir)/libvoxdag.so
	install -m 644 $(PUBLIC_HEADERS) $(DESTDIR)$(includedir)/voxdag/
	install -d $(DESTDIR)$(datadir)/voxdag/viewer
	install -m 644 $(wildcard viewer/*.html viewer/*.js) $(DESTDIR)$(datadir)/voxdag/viewer/
	sed -e 's|@PREFIX@|$(PREFIX)|' -e 's|@VERSION@|$(LIB_VERSION)|' \
	    -e 's|@LIBDIR@|$(call pc_dir,$(libdir))|' \
	    -e 's|@INCLUDEDIR@|$(call pc_dir,$(includedir))|' \
	    -e 's|@LIBS_PRIVATE@|$(LIB_LIBS) -lstdc++|' \
	    stages/lib/voxdag.pc.in > $(DESTDIR)$(pkgconfigdir)/voxdag.pc

# Removes what install wrote (the whole include/voxdag/: every header in
# it is ours, whichever per-concern headers an older version installed).
uninstall:
	rm -f $(addprefix $(DESTDIR)$(bindir)/,$(notdir $(ALL_BINS)))
	rm -f $(DESTDIR)$(libdir)/libvoxdag.a $(DESTDIR)$(libdir)/libvoxdag.so \
	      $(DESTDIR)$(libdir)/$(SONAME) $(DESTDIR)$(libdir)/$(notdir $(SHLIB))
	rm -rf $(DESTDIR)$(includedir)/voxdag $(DESTDIR)$(datadir)/voxdag
	rm -f $(DESTDIR)$(pkgconfigdir)/voxdag.pc

# `make PIPELINE=config/x.yaml` builds what is missing and runs that
# pipeline (resuming where a previous run stopped); `make run` runs the
# default one on the bundled bunny.
PIPELINE ?=
ifneq ($(PIPELINE),)
.DEFAULT_GOAL := pipeline
endif

pipeline: deps
	@$(MAKE) --no-print-directory -j$(JOBS) all
	$(OUT)/bin/voxdag run $(PIPELINE)

run:
	@$(MAKE) --no-print-directory pipeline PIPELINE=config/default.yaml

# Sub-makes build with every core (CI's `make test` has no -j of its own).
JOBS ?= $(shell nproc)

test: deps
	@$(MAKE) --no-print-directory -j$(JOBS) test-build
	@tests/run.sh

# What the tests run: the release executables and libraries (CLI tests;
# install.sh installs them, so it only copies), the sanitizer build's
# executables and unit tests, the fuzz targets. One sub-make, so the three
# builds share one job server and keep every core busy (each has long
# compiles, io/vdb*.cc, that would otherwise leave a core idle).
test-build: test-build-release test-build-sanitize fuzz-build
test-build-release: viewer-test-deps
	@$(MAKE) --no-print-directory all lib $(OUT)/tests/fs_shutdown

# The viewer's test dependencies (puppeteer-core, pngjs) at the versions
# of tests/viewer/package-lock.json; never a browser of npm's own
# (PUPPETEER_SKIP_DOWNLOAD): the tests drive Debian's /usr/bin/chromium.
# Without npm (make deps not run) tests/cli/viewer.sh says SKIP.
VIEWER_NPM := tests/viewer/node_modules/.package-lock.json
viewer-test-deps: $(VIEWER_NPM)
$(VIEWER_NPM): tests/viewer/package-lock.json tests/viewer/package.json
	@if command -v npm >/dev/null; then \
		PUPPETEER_SKIP_DOWNLOAD=1 npm ci --prefix tests/viewer --no-audit \
			--no-fund --loglevel=error >/dev/null && touch $@; \
	else echo "make: no npm for the viewer's tests (make deps installs it)"; fi
test-build-sanitize:
	@$(MAKE) --no-print-directory config=sanitize all tests

bench: deps
	@$(MAKE) --no-print-directory -j$(JOBS) all $(OUT)/bench/zstd_levels $(OUT)/bench/translation $(OUT)/bench/edit_site \
		$(OUT)/bench/colour_lookup
	@$(MAKE) --no-print-directory -j$(JOBS) config=nofsync all
	@tests/bench.sh

# Fuzzing (libFuzzer, Debian's clang): one target per reader,
# tests/fuzz/fuzz_*.c, over the library compiled again with clang into
# $(O)/fuzz/. `make fuzz` runs each for FUZZ_SECONDS from its seed corpus
# tests/fuzz/corpus/<target>/ (new inputs go to $(O)/fuzz/corpus/, the
# crashes to $(O)/fuzz/crash/); `make test` runs each for a few seconds
# (tests/cli/fuzz.sh).
FUZZ_SECONDS ?= 600
FUZZ_CC  := clang
FUZZ_CXX := clang++
FUZZ_OUT := $(O)/fuzz
FUZZ_SAN := -fsanitize=address,undefined -fno-sanitize-recover=undefined \
            -fno-omit-frame-pointer
FUZZ_CFLAGS := -std=c11 $(WARN) -Wno-unknown-warning-option -g -O1 \
               $(FUZZ_SAN) -fsanitize=fuzzer-no-link
FUZZ_CXXFLAGS := -std=c++17 -Wall -Wextra -Werror -g -O1 $(FUZZ_SAN) \
                 -fsanitize=fuzzer-no-link
# Every library file but the OpenVDB writer (io/vdb_write.cc: no target
# writes grids, and it is the longest compile of the library).
FUZZ_LIB_OBJ := $(LIB_C:stages/lib/%.c=$(FUZZ_OUT)/obj/lib/%.o) \
                $(patsubst stages/lib/%.cc,$(FUZZ_OUT)/obj/lib/%.o, \
                  $(filter-out stages/lib/io/vdb_write.cc,$(LIB_CC)))
FUZZ_LIB := $(FUZZ_OUT)/lib/libvoxdag.a
FUZZ_SRC := $(wildcard tests/fuzz/fuzz_*.c)
FUZZ_BINS := $(FUZZ_SRC:tests/fuzz/%.c=$(FUZZ_OUT)/%)

$(FUZZ_OUT)/obj/lib/%.o: stages/lib/%.c $(HEADERS)
	@mkdir -p $(@D)
	$(FUZZ_CC) $(CPPFLAGS) $(FUZZ_CFLAGS) -c -o $@ $<

$(FUZZ_OUT)/obj/lib/%.o: stages/lib/%.cc $(HEADERS)
	@mkdir -p $(@D)
	$(FUZZ_CXX) $(CPPFLAGS) $(FUZZ_CXXFLAGS) -c -o $@ $<

$(FUZZ_LIB): $(FUZZ_LIB_OBJ)
	@mkdir -p $(@D)
	rm -f $@ && ar rcs $@ $^

# The YAML target reads pipelines with the runner's own config.c.
$(FUZZ_OUT)/obj/pipeline/%.o: pipeline/%.c pipeline/pipeline.h $(HEADERS)
	@mkdir -p $(@D)
	$(FUZZ_CC) $(CPPFLAGS) $(FUZZ_CFLAGS) -Wno-format-truncation -c -o $@ $<

$(FUZZ_OUT)/fuzz_config: $(FUZZ_OUT)/obj/pipeline/config.o
$(FUZZ_OUT)/fuzz_%: tests/fuzz/fuzz_%.c $(wildcard tests/fuzz/*.h) $(FUZZ_LIB) $(HEADERS)
	@mkdir -p $(@D)
	$(FUZZ_CC) $(CPPFLAGS) -Ipipeline -Itests/fuzz $(FUZZ_CFLAGS) -c -o $@.o $<
	$(FUZZ_CXX) $(FUZZ_SAN) -fsanitize=fuzzer -o $@ $@.o \
		$(filter %.o,$(filter-out $@.o,$^)) $(FUZZ_LIB) -lyaml $(LDLIBS)

fuzz-build: $(FUZZ_BINS)

fuzz: fuzz-build
	@failed=; for t in $(FUZZ_BINS); do \
		n=$$(basename $$t); \
		seeds=tests/fuzz/corpus/$${n#fuzz_}; \
		test -d $$seeds || { echo "fuzz: no seed corpus $$seeds"; exit 1; }; \
		mkdir -p $(FUZZ_OUT)/corpus/$$n $(FUZZ_OUT)/crash/$$n; \
		echo "== $$n for $(FUZZ_SECONDS) s"; \
		$$t -max_total_time=$(FUZZ_SECONDS) -timeout=10 -rss_limit_mb=2048 \
		    -artifact_prefix=$(FUZZ_OUT)/crash/$$n/ -print_final_stats=1 \
		    $(FUZZ_OUT)/corpus/$$n $$seeds || failed="$$failed $$n"; \
	done; \
	if [ -n "$$failed" ]; then \
		echo "fuzz: crashes in$$failed (inputs in $(FUZZ_OUT)/crash/)"; exit 1; \
	fi

clean:
	rm -rf out
