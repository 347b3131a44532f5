# VTSIM_SANITIZE=address -> ASan + UBSan (all UB checks fatal); =thread -> TSan.
if(VTSIM_SANITIZE STREQUAL "address")
  add_compile_options(-fsanitize=address,undefined -fno-sanitize-recover=all -fno-omit-frame-pointer)
  add_link_options(-fsanitize=address,undefined)
elseif(VTSIM_SANITIZE STREQUAL "thread")
  add_compile_options(-fsanitize=thread -fno-omit-frame-pointer)
  # target_clones' ifunc resolvers run before the TSan runtime starts and crash at load.
  add_compile_definitions(VTSIM_NO_TARGET_CLONES)
  add_link_options(-fsanitize=thread)
elseif(NOT VTSIM_SANITIZE STREQUAL "")
  message(FATAL_ERROR "VTSIM_SANITIZE must be '', 'address' or 'thread' (got '${VTSIM_SANITIZE}')")
endif()
