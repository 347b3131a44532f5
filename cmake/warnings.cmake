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
  # clang (the sanitizer builds of scripts/test.sh: it compiles them in ~60 % of GCC's time) flags
  # float operands promoted inside double expressions under -Wdouble-promotion, which GCC accepts,
  # and ignores GCC's [[gnu::always_inline]] on lambdas with a warning. The Release build (GCC,
  # -Werror) keeps both checks; clang drops these two.
  if(CMAKE_CXX_COMPILER_ID STREQUAL "Clang")
    target_compile_options(${target} PRIVATE -Wno-double-promotion -Wno-ignored-attributes)
  endif()
  if(VTSIM_WERROR)
    target_compile_options(${target} PRIVATE -Werror)
  endif()
endfunction()
