# Per-target warnings (no directory-wide flags): call zerog_warnings(<target>).
function(zerog_warnings target)
  target_compile_options(${target} PRIVATE -Wall -Wextra -Wpedantic -Wshadow -Wconversion
                                           -Wno-sign-conversion -Wnon-virtual-dtor)
  if(ZEROG_WERROR)
    target_compile_options(${target} PRIVATE -Werror)
  endif()
endfunction()
