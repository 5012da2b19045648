#include "server/malloc_arenas.hpp"

#include <malloc.h>

#include <cstdlib>
#include <cstring>

namespace locaid::server {

MallocArenaPolicy ChooseMallocArenaPolicy(size_t configured, const char* malloc_arena_max_env,
                                          const char* glibc_tunables_env) {
  // A user who set the bound for this process has said what they want; glibc
  // has already applied it, and a mallopt here would silently replace it.
  const bool env_sets_it = (malloc_arena_max_env != nullptr && *malloc_arena_max_env != '\0') ||
                           (glibc_tunables_env != nullptr &&
                            std::strstr(glibc_tunables_env, "glibc.malloc.arena_max=") != nullptr);
  if (env_sets_it) return {MallocArenaPolicy::Source::kEnvironment, 0};
  if (configured == 0) return {MallocArenaPolicy::Source::kGlibcDefault, 0};
  return {MallocArenaPolicy::Source::kConfig, configured};
}

MallocArenaPolicy ApplyMallocArenaMax(size_t configured) {
  MallocArenaPolicy policy =
      ChooseMallocArenaPolicy(configured, std::getenv("MALLOC_ARENA_MAX"), std::getenv("GLIBC_TUNABLES"));
  // Under another allocator (jemalloc or tcmalloc preloaded) this reaches
  // glibc's malloc, which then serves nothing: harmless.
  if (policy.source == MallocArenaPolicy::Source::kConfig &&
      ::mallopt(M_ARENA_MAX, static_cast<int>(policy.arena_max)) != 1) {
    policy = {};
  }
  return policy;
}

}  // namespace locaid::server
