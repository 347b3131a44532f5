// Default options of the sanitizer runtime, compiled into every executable of the ASan+UBSan and
// fuzz builds (cmake/sanitizers.cmake), so that `vtsim`, the test runner, its `vtsim` children and
// the fuzz executables run the same way with or without ASAN_OPTIONS set (the environment still
// overrides any of them).
//
// intercept_tls_get_addr=0: up to GCC 13's and LLVM 16's runtimes, the __tls_get_addr interceptor
// takes a dynamic TLS block whose address is 16 mod 4096 for one with glibc 2.19's header and reads
// the two words before it as the block's start and size (sanitizer_tls_get_addr.cpp,
// google/sanitizers#1322). glibc >= 2.25 has no such header: a block that lands on that offset by
// chance records a garbage range, and LeakSanitizer's stop-the-world tracer dies scanning it at
// exit ("Tracer caught signal 11 ... LeakSanitizer has encountered a fatal error", exit 134 with
// abort_on_error) after the process did all its work. The image module (OpenImageIO and its ~250
// libraries, thread_local in several) makes dynamic TLS blocks in every thread that reads an image;
// CI saw the crash in `vtsim store verify` and in the fuzz corpus, at random. The cost: LeakSanitizer
// no longer scans dynamic TLS for roots, so a block reachable only from a dlopen'ed library's
// thread_local would be reported as leaked (none is: the ASan suite passes with it).
extern "C" const char* __asan_default_options();
extern "C" const char* __asan_default_options() { return "intercept_tls_get_addr=0"; }
