# VTSIM_SANITIZE=address -> ASan + UBSan (all UB checks fatal); =thread -> TSan.
if(VTSIM_SANITIZE STREQUAL "address")
  add_compile_options(-fsanitize=address,undefined -fno-sanitize-recover=all -fno-omit-frame-pointer)
  add_link_options(-fsanitize=address,undefined)
elseif(VTSIM_SANITIZE STREQUAL "thread")
  add_compile_options(-fsanitize=thread -fno-omit-frame-pointer)
  # target_clones' ifunc resolvers run before the TSan runtime starts and crash at load.
  add_compile_definitions(VTSIM_NO_TARGET_CLONES)
  add_link_options(-fsanitize=thread)
elseif(VTSIM_SANITIZE STREQUAL "fuzz")
  # libFuzzer's coverage instrumentation plus ASan+UBSan (clang only; scripts/fuzz.sh): the fuzz
  # executables of tests/fuzz link -fsanitize=fuzzer, which brings libFuzzer's main.
  if(NOT CMAKE_CXX_COMPILER_ID STREQUAL "Clang")
    message(FATAL_ERROR "VTSIM_SANITIZE=fuzz needs clang (CMAKE_CXX_COMPILER=clang++)")
  endif()
  add_compile_options(-fsanitize=fuzzer-no-link,address,undefined -fno-sanitize-recover=all -fno-omit-frame-pointer)
  add_compile_definitions(VTSIM_NO_TARGET_CLONES)  # one code path for the coverage feedback
  add_link_options(-fsanitize=address,undefined)
elseif(NOT VTSIM_SANITIZE STREQUAL "")
  message(FATAL_ERROR "VTSIM_SANITIZE must be '', 'address', 'thread' or 'fuzz' (got '${VTSIM_SANITIZE}')")
endif()

# Every executable of the ASan and fuzz builds carries the runtime's default options
# (cmake/sanitizer_options.cpp: why LeakSanitizer needs intercept_tls_get_addr=0 here).
function(vtsim_sanitizer_defaults target)
  if(VTSIM_SANITIZE STREQUAL "address" OR VTSIM_SANITIZE STREQUAL "fuzz")
    target_sources(${target} PRIVATE ${PROJECT_SOURCE_DIR}/cmake/sanitizer_options.cpp)
  endif()
endfunction()
