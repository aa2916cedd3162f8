# Per-target defaults: C++17, warnings, optional sanitizers. No global flags.
#
# SNOW_SANITIZE: AddressSanitizer + UndefinedBehaviorSanitizer (UB aborts:
#   -fno-sanitize-recover) + libstdc++'s container bounds checks. tools/test builds CI this way; the run-time options
#   and the LSan suppressions for Mesa/LLVM live in tests/sanitizers/.
# SNOW_FUZZ: the same sanitizers plus libFuzzer's coverage instrumentation
#   (clang only); the fuzz targets in tests/fuzz link -fsanitize=fuzzer.
if(SNOW_SANITIZE OR SNOW_FUZZ)
  # Sanitizer run-time defaults compiled into each executable (see the .in file).
  file(STRINGS ${PROJECT_SOURCE_DIR}/tests/sanitizers/lsan.supp supp_lines REGEX "^[a-z_]+:")
  list(JOIN supp_lines "\\n" SNOW_LSAN_SUPPRESSIONS)
  configure_file(${PROJECT_SOURCE_DIR}/tests/sanitizers/sanitizer_defaults.cpp.in
                 ${CMAKE_BINARY_DIR}/sanitizer_defaults.cpp @ONLY)
  set_property(DIRECTORY ${PROJECT_SOURCE_DIR} APPEND PROPERTY CMAKE_CONFIGURE_DEPENDS
               ${PROJECT_SOURCE_DIR}/tests/sanitizers/lsan.supp)
endif()

function(snow_target_defaults target)
  target_compile_features(${target} PUBLIC cxx_std_17)
  set_target_properties(${target} PROPERTIES CXX_EXTENSIONS OFF)
  target_compile_options(${target} PRIVATE -Wall -Wextra -Wpedantic -Wno-missing-field-initializers)
  if(SNOW_WERROR)
    target_compile_options(${target} PRIVATE -Werror)
  endif()
  if(SNOW_SANITIZE OR SNOW_FUZZ)
    # float-cast-overflow: a float out of an integer's range converted to it
    # (clang's "undefined" holds it, GCC's does not).
    set(sanitizers address,undefined,float-cast-overflow)
    if(SNOW_FUZZ)
      set(sanitizers fuzzer-no-link,${sanitizers})
    endif()
    target_compile_options(${target} PUBLIC -fsanitize=${sanitizers} -fno-omit-frame-pointer
                                            -fno-sanitize-recover=undefined,float-cast-overflow)
    target_link_options(${target} PUBLIC -fsanitize=address,undefined,float-cast-overflow)
    # Bounds checks in the standard containers: ASan misses a read past a
    # vector's size but within its capacity.
    target_compile_definitions(${target} PUBLIC _GLIBCXX_ASSERTIONS)
    get_target_property(type ${target} TYPE)
    if(type STREQUAL "EXECUTABLE")
      target_sources(${target} PRIVATE ${CMAKE_BINARY_DIR}/sanitizer_defaults.cpp)
    endif()
  endif()
endfunction()
