#pragma once
// printf-style formatting into a std::string for the initializer's status
// messages (checked by the compiler like printf).
#include <cstdarg>
#include <cstdio>
#include <string>

namespace rilo::init_detail {

__attribute__((format(printf, 1, 2))) inline std::string strprintf(const char* fmt, ...) {
  char buf[512];
  va_list args;
  va_start(args, fmt);
  std::vsnprintf(buf, sizeof buf, fmt, args);
  va_end(args);
  return buf;
}

}  // namespace rilo::init_detail
