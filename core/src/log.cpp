#include "hwr/core/log.hpp"

#include <atomic>
#include <cstdio>
#include <cstring>
#include <mutex>

namespace hwr::core {
namespace {

std::atomic<int> g_level{static_cast<int>(LogLevel::kInfo)};
std::mutex g_sink_mutex;
LogSink g_sink = nullptr;
void* g_sink_user = nullptr;

void stderr_sink(LogLevel level, const char* module, const char* message, void*) {
  std::fprintf(stderr, "[%s] %s: %s\n", to_string(level), module, message);
}

}  // namespace

void set_log_level(LogLevel level) { g_level.store(static_cast<int>(level)); }
LogLevel log_level() { return static_cast<LogLevel>(g_level.load()); }

void set_log_sink(LogSink sink, void* user) {
  std::lock_guard<std::mutex> lock(g_sink_mutex);
  g_sink = sink;
  g_sink_user = user;
}

const char* to_string(LogLevel level) {
  switch (level) {
    case LogLevel::kDebug:
      return "debug";
    case LogLevel::kInfo:
      return "info";
    case LogLevel::kWarn:
      return "warn";
    case LogLevel::kError:
      return "error";
    case LogLevel::kOff:
      return "off";
  }
  return "?";
}

bool parse_log_level(const char* text, LogLevel* out) {
  for (LogLevel l : {LogLevel::kDebug, LogLevel::kInfo, LogLevel::kWarn, LogLevel::kError, LogLevel::kOff}) {
    if (std::strcmp(text, to_string(l)) == 0) {
      *out = l;
      return true;
    }
  }
  return false;
}

void vlog(LogLevel level, const char* module, const char* fmt, va_list args) {
  if (static_cast<int>(level) < g_level.load() || level == LogLevel::kOff) return;
  char buf[1024];  // longer messages are truncated, never allocated
  std::vsnprintf(buf, sizeof(buf), fmt, args);
  std::lock_guard<std::mutex> lock(g_sink_mutex);
  (g_sink ? g_sink : stderr_sink)(level, module, buf, g_sink_user);
}

void log(LogLevel level, const char* module, const char* fmt, ...) {
  va_list args;
  va_start(args, fmt);
  vlog(level, module, fmt, args);
  va_end(args);
}

}  // namespace hwr::core
