# All third-party dependencies come from Debian 12 packages (scripts/install-deps.sh).
# Nothing is downloaded at configure or build time.
find_package(Threads REQUIRED)
find_package(Eigen3 3.3 REQUIRED NO_MODULE)
find_package(OpenMP REQUIRED COMPONENTS CXX)
find_package(nlohmann_json 3 REQUIRED)

# CGAL 5.5 (header-only); GMP/MPFR come with it for exact constructions.
set(CGAL_DO_NOT_WARN_ABOUT_CMAKE_BUILD_TYPE TRUE)
find_package(CGAL 5.5 REQUIRED)

# GeographicLib ships its CMake module in /usr/share/cmake/geographiclib.
find_package(GeographicLib REQUIRED)

# PROJ
find_package(PROJ QUIET CONFIG)
if(NOT PROJ_FOUND)
  find_package(PkgConfig REQUIRED)
  pkg_check_modules(PROJ REQUIRED IMPORTED_TARGET proj)
  add_library(PROJ::proj ALIAS PkgConfig::PROJ)
endif()

# GDAL (footprints from OGR sources; private to citylod_io). Debian 12's
# libgdal-dev (3.6) ships GDALConfig.cmake (target GDAL::GDAL); CMake's own
# FindGDAL module is the fallback and defines the same target.
find_package(GDAL CONFIG QUIET)
if(NOT GDAL_FOUND)
  find_package(GDAL REQUIRED)
endif()

# PCL: its config drags in VTK and fails on MPI; we use none of it (no pcl_io).
set(CMAKE_DISABLE_FIND_PACKAGE_VTK ON)
find_package(PCL 1.12 REQUIRED COMPONENTS common search kdtree filters segmentation sample_consensus)

# meshoptimizer (EXT_meshopt_compression of the glbs; private to citylod_io).
# Debian 12: libmeshoptimizer-dev 0.18, target meshoptimizer::meshoptimizer.
find_package(meshoptimizer REQUIRED)

# tinygltf (Debian ships the header and a small library)
find_path(TINYGLTF_INCLUDE_DIR tiny_gltf.h PATH_SUFFIXES tinygltf REQUIRED)
find_library(TINYGLTF_LIBRARY tinygltf)
