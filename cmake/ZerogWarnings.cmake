# Per-target warnings (no directory-wide flags): call zerog_warnings(<target>) on every target.
# It also applies the sanitizers of a sanitizer build (ZEROG_SANITIZE, presets `asan`, `tsan`),
# so that every zerog target, and only those, is instrumented the same way.
set(ZEROG_SANITIZE "" CACHE STRING
    "Sanitizers for every zerog target: empty, 'address,undefined' or 'thread'")
# Checks of those left out (-fno-sanitize=...), e.g. the asan preset's UBSan checks on every
# memory access that ASan already makes (null, object-size), or that cost most of the compile
# time on Eigen code and mean nothing on x86-64 (alignment, pointer-overflow, vptr).
set(ZEROG_SANITIZE_EXCLUDE "" CACHE STRING "Sanitizer checks left out: empty or a comma list")
# The fuzz build (preset `fuzz`, tests/fuzz): clang's libFuzzer. Every zerog target gets
# ASan + UBSan as above plus libFuzzer's coverage instrumentation (-fsanitize=fuzzer-no-link);
# the fuzz targets themselves link libFuzzer's main (zerog_fuzz_target in tests/fuzz).
option(ZEROG_FUZZ "Build the libFuzzer targets (tests/fuzz); needs clang" OFF)
if(ZEROG_FUZZ)
  if(NOT CMAKE_CXX_COMPILER_ID STREQUAL "Clang")
    message(FATAL_ERROR "ZEROG_FUZZ needs clang (libFuzzer), the compiler is "
                        "${CMAKE_CXX_COMPILER_ID}: configure with the preset `fuzz`")
  endif()
  if(ZEROG_SANITIZE AND NOT ZEROG_SANITIZE STREQUAL "address,undefined")
    message(FATAL_ERROR "ZEROG_FUZZ runs with ZEROG_SANITIZE=address,undefined, "
                        "not '${ZEROG_SANITIZE}'")
  endif()
  set(ZEROG_SANITIZE "address,undefined")
endif()

function(zerog_warnings target)
  target_compile_options(${target} PRIVATE -Wall -Wextra -Wpedantic -Wshadow -Wconversion
                                           -Wno-sign-conversion -Wnon-virtual-dtor)
  if(ZEROG_WERROR)
    target_compile_options(${target} PRIVATE -Werror)
  endif()
  if(ZEROG_SANITIZE)
    # Any finding ends the program with an error (no "recover and carry on").
    set(instrument ${ZEROG_SANITIZE})
    if(ZEROG_FUZZ)
      set(instrument "fuzzer-no-link,${ZEROG_SANITIZE}")
    endif()
    target_compile_options(${target} PRIVATE -fsanitize=${instrument}
                                             -fno-sanitize-recover=all -fno-omit-frame-pointer)
    if(ZEROG_SANITIZE_EXCLUDE)
      target_compile_options(${target} PRIVATE -fno-sanitize=${ZEROG_SANITIZE_EXCLUDE})
    endif()
    target_link_options(${target} PRIVATE -fsanitize=${ZEROG_SANITIZE})
  endif()
endfunction()
