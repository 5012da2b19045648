// glibc malloc's arena bound for locaid-server (ServerConfig::malloc_arena_max;
// docs/reliability.md "Memory under fan-out"). glibc gives a thread that finds
// the arenas busy one of its own, up to 8 per core; the server starts threads
// for every session (pipeline, fan-out, decode helper) and gRPC's executor
// threads come and go with the load, so each round of sessions and streams
// left its freed memory in more arenas, each keeping its high-water mark: RSS
// grew round after round although the heap in use did not. Two arenas kept
// RSS level, with no difference in streaming delay that 2 cores could show.
#pragma once

#include <cstddef>

namespace locaid::server {

// What bounds the arenas: the environment (MALLOC_ARENA_MAX, or
// glibc.malloc.arena_max in GLIBC_TUNABLES; glibc read it itself and it
// wins), the configured malloc_arena_max, or nothing (0 = glibc's default).
struct MallocArenaPolicy {
  enum class Source { kEnvironment, kConfig, kGlibcDefault };
  Source source = Source::kGlibcDefault;
  size_t arena_max = 0;  // the bound mallopt sets (kConfig only)
};

// Decides from the configured value and the two environment variables'
// values (nullptr = unset). Pure, for tests.
MallocArenaPolicy ChooseMallocArenaPolicy(size_t configured, const char* malloc_arena_max_env,
                                          const char* glibc_tunables_env);

// Reads the environment and, for kConfig, calls mallopt(M_ARENA_MAX). Call it
// before the process starts a second thread: arenas already made stay.
// Returns the policy applied (a kConfig that mallopt refused comes back as
// kGlibcDefault).
MallocArenaPolicy ApplyMallocArenaMax(size_t configured);

}  // namespace locaid::server
