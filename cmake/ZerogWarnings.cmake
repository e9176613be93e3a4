# Per-target warnings (no directory-wide flags): call zerog_warnings(<target>) on every target.
# It also applies the sanitizers of a sanitizer build (ZEROG_SANITIZE, presets `asan`, `tsan`),
# so that every zerog target, and only those, is instrumented the same way.
set(ZEROG_SANITIZE "" CACHE STRING
    "Sanitizers for every zerog target: empty, 'address,undefined' or 'thread'")

function(zerog_warnings target)
  target_compile_options(${target} PRIVATE -Wall -Wextra -Wpedantic -Wshadow -Wconversion
                                           -Wno-sign-conversion -Wnon-virtual-dtor)
  if(ZEROG_WERROR)
    target_compile_options(${target} PRIVATE -Werror)
  endif()
  if(ZEROG_SANITIZE)
    # Any finding ends the program with an error (no "recover and carry on").
    target_compile_options(${target} PRIVATE -fsanitize=${ZEROG_SANITIZE}
                                             -fno-sanitize-recover=all -fno-omit-frame-pointer)
    target_link_options(${target} PRIVATE -fsanitize=${ZEROG_SANITIZE})
  endif()
endfunction()
