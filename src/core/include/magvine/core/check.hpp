#pragma once
/// Programmer-error assertions. Bad *input* is reported with InputError instead.

#include <cstdio>
#include <cstdlib>

#ifndef NDEBUG
#define MAGVINE_ASSERT(cond)                                                                  \
  do {                                                                                        \
    if (!(cond)) {                                                                            \
      std::fprintf(stderr, "%s:%d: assertion failed: %s\n", __FILE__, __LINE__, #cond);       \
      std::abort();                                                                           \
    }                                                                                         \
  } while (false)
#else
#define MAGVINE_ASSERT(cond) ((void)0)
#endif
