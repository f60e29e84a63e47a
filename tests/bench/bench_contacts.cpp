// placeholder: filled in by the anatomy work
#include <benchmark/benchmark.h>
BENCHMARK_MAIN();
