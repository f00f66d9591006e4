// A stand-in for a component container: links nothing of ContextROS, dlopen()s the component
// libraries named on the command line, starts each, and stops them on SIGINT/SIGTERM. The
// components share the process's one runtime and participant only because
// libcontextros_core.so and libcontextros_ros.so are shared libraries.
#include <dlfcn.h>
#include <pthread.h>
#include <signal.h>

#include <cstdio>
#include <memory>
#include <vector>

namespace {

struct Library {
  void* handle;
  explicit Library(const char* path) : handle(dlopen(path, RTLD_NOW | RTLD_LOCAL)) {}
  ~Library() {
    if (handle != nullptr) dlclose(handle);
  }
  Library(const Library&) = delete;
  Library& operator=(const Library&) = delete;
  template <typename Function>
  Function* symbol(const char* name) const {
    return reinterpret_cast<Function*>(dlsym(handle, name));
  }
};

using Start = void(int, const char* const*);
using Stop = void();

}  // namespace

int main(int argc, char** argv) {
  sigset_t signals;
  sigemptyset(&signals);
  sigaddset(&signals, SIGINT);
  sigaddset(&signals, SIGTERM);
  pthread_sigmask(SIG_BLOCK, &signals, nullptr);

  std::vector<std::unique_ptr<Library>> libraries;
  for (int i = 1; i < argc; ++i) {
    auto library = std::make_unique<Library>(argv[i]);
    if (library->handle == nullptr) {
      std::fprintf(stderr, "components_host: %s\n", dlerror());
      return 1;
    }
    library->symbol<Start>("contextros_component_start")(1, argv);
    libraries.push_back(std::move(library));
  }
  std::printf("ready\n");
  std::fflush(stdout);
  int received = 0;
  sigwait(&signals, &received);
  for (auto it = libraries.rbegin(); it != libraries.rend(); ++it) {
    (*it)->symbol<Stop>("contextros_component_stop")();
  }
  return 0;
}
