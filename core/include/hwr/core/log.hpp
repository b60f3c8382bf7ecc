#pragma once
// Logger (STYLE.md practice 5: libraries never print; they log). printf-style, formatted into a
// stack buffer (no heap allocation), one line per call, handed to a replaceable sink. The default
// sink writes "<level> <module>: <message>" to stderr. Thread-safe.

#include <cstdarg>

namespace hwr::core {

enum class LogLevel { kDebug = 0, kInfo, kWarn, kError, kOff };

// A sink receives one formatted line without a trailing newline.
using LogSink = void (*)(LogLevel level, const char* module, const char* message, void* user);

void set_log_level(LogLevel level);
LogLevel log_level();
// nullptr restores the stderr sink.
void set_log_sink(LogSink sink, void* user = nullptr);
const char* to_string(LogLevel level);
// Parses "debug|info|warn|error|off"; returns false when unknown.
bool parse_log_level(const char* text, LogLevel* out);

void log(LogLevel level, const char* module, const char* fmt, ...) __attribute__((format(printf, 3, 4)));
void vlog(LogLevel level, const char* module, const char* fmt, va_list args);

}  // namespace hwr::core

#define HWR_LOG_DEBUG(module, ...) ::hwr::core::log(::hwr::core::LogLevel::kDebug, module, __VA_ARGS__)
#define HWR_LOG_INFO(module, ...) ::hwr::core::log(::hwr::core::LogLevel::kInfo, module, __VA_ARGS__)
#define HWR_LOG_WARN(module, ...) ::hwr::core::log(::hwr::core::LogLevel::kWarn, module, __VA_ARGS__)
#define HWR_LOG_ERROR(module, ...) ::hwr::core::log(::hwr::core::LogLevel::kError, module, __VA_ARGS__)
