# Third-party packages, all from Debian (tools/install-deps.sh installs them).
find_package(Eigen3 3.3 REQUIRED NO_MODULE)
find_package(yaml-cpp REQUIRED)
find_package(nlohmann_json 3 REQUIRED)
find_package(CLI11 REQUIRED)

# LBFGSpp (header-only, MIT): the design's bounded L-BFGS-B. Debian ships the headers without a CMake config.
find_path(LBFGSPP_INCLUDE_DIR LBFGSB.h PATH_SUFFIXES include REQUIRED)
add_library(magvine_lbfgspp INTERFACE)
target_include_directories(magvine_lbfgspp SYSTEM INTERFACE ${LBFGSPP_INCLUDE_DIR})
add_library(magvine::lbfgspp ALIAS magvine_lbfgspp)

# Bullet in double precision: Debian ships *-float64 libraries beside the float ones, described by
# bullet-float64.pc, whose Cflags carry -DBT_USE_DOUBLE_PRECISION. Mixing precisions corrupts memory
# silently, so nothing in magvine may use the plain `bullet` package.
find_package(PkgConfig REQUIRED)
pkg_check_modules(BULLET_F64 REQUIRED IMPORTED_TARGET bullet-float64)
add_library(magvine_bullet INTERFACE)
target_link_libraries(magvine_bullet INTERFACE PkgConfig::BULLET_F64)
target_compile_definitions(magvine_bullet INTERFACE BT_USE_DOUBLE_PRECISION)
add_library(magvine::bullet ALIAS magvine_bullet)

# Anatomy: assimp reads the mesh formats users export from 3D Slicer and CAD; Embree's BVH builder builds the
# collision world's hierarchy. Both through their CMake configs.
find_package(assimp 5 REQUIRED CONFIG)
find_package(embree 3 REQUIRED CONFIG)

if(MAGVINE_WITH_RENDER)
  find_package(OpenCV 4 REQUIRED COMPONENTS core imgproc imgcodecs videoio)
  find_package(Threads REQUIRED)
endif()

if(MAGVINE_WITH_CT)
  # libnifti2 (public domain) reads NIfTI-1/2 label maps, gzip included; OpenVDB (MPL-2.0) turns them into level sets
  # and surfaces. Debian's NIFTI CMake config points at /usr/lib/libznz.so.3.0.0, which the package does not install,
  # so the library is found by hand; OpenVDB ships a find module (not a config) beside its other modules.
  find_path(NIFTI_INCLUDE_DIR nifti2_io.h PATH_SUFFIXES nifti REQUIRED)
  find_library(NIFTI2_LIBRARY nifti2 REQUIRED)
  find_library(ZNZ_LIBRARY znz REQUIRED)
  find_package(ZLIB REQUIRED)
  add_library(magvine_nifti INTERFACE)
  target_include_directories(magvine_nifti SYSTEM INTERFACE ${NIFTI_INCLUDE_DIR})
  target_link_libraries(magvine_nifti INTERFACE ${NIFTI2_LIBRARY} ${ZNZ_LIBRARY} ZLIB::ZLIB m)
  add_library(magvine::nifti ALIAS magvine_nifti)
  list(APPEND CMAKE_MODULE_PATH /usr/lib/x86_64-linux-gnu/cmake/OpenVDB)
  find_package(OpenVDB REQUIRED)
endif()

if(MAGVINE_WITH_MPM)
  find_package(OpenMP REQUIRED COMPONENTS CXX)  # GCC's libgomp: the MPM solver's loops over particles and nodes
endif()

if(MAGVINE_BUILD_TESTS)
  find_package(GTest REQUIRED)
endif()
if(MAGVINE_BUILD_BENCHMARKS)
  find_package(benchmark REQUIRED)
endif()
