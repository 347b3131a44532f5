function(vtsim_warnings target)
  target_compile_options(${target} PRIVATE -Wall -Wextra -Wpedantic -Wshadow -Wnon-virtual-dtor
    -Wold-style-cast -Wcast-align -Woverloaded-virtual -Wnull-dereference -Wdouble-promotion
    -Wformat=2 -Wimplicit-fallthrough)
  # GCC 12's -Wnull-dereference reports libstdc++ paths inlined into CLI11 (std::string inside
  # CLI::detail::split) as null dereferences once -fsanitize=thread changes inlining: a false
  # positive in system headers, so the TSan build drops that one warning (Release and ASan keep it).
  if(VTSIM_SANITIZE STREQUAL "thread")
    target_compile_options(${target} PRIVATE -Wno-null-dereference)
  endif()
  if(VTSIM_WERROR)
    target_compile_options(${target} PRIVATE -Werror)
  endif()
endfunction()
