// ProgressLine: the one way vdrig's commands show progress on stdout. On a terminal the line is redrawn in place
// ('\r'); when stdout is a file or a pipe (logs, CI) redraws would pile up on one line (40 KB for a 188-view
// capture), so a plain newline-ended line is printed each time another 10 % is done, and at the end.
#pragma once

#include <unistd.h>

#include <cstdarg>
#include <cstdio>

namespace vdrig::app {

class ProgressLine {
 public:
  ProgressLine() : terminal_(::isatty(::fileno(stdout)) == 1) {}
  ProgressLine(const ProgressLine&) = delete;
  ProgressLine& operator=(const ProgressLine&) = delete;
  ~ProgressLine() { finish(); }

  /// `done` of `total` units are done; the line reads `format` (printf) followed by the percentage when not on a
  /// terminal. Redraws on a terminal; otherwise prints only when a further 10 % step is reached.
  __attribute__((format(printf, 4, 5))) void update(long done, long total, const char* format, ...) {
    const int percent = total > 0 ? static_cast<int>(100 * done / total) : 100;
    if (!terminal_ && percent < next_percent_) return;
    char text[512];
    va_list args;
    va_start(args, format);
    std::vsnprintf(text, sizeof text, format, args);
    va_end(args);
    if (terminal_) {
      std::printf("\r%s   ", text);
      open_line_ = true;
    } else {
      std::printf("%s  (%d %%)\n", text, percent);
      next_percent_ = percent / 10 * 10 + 10;
    }
    std::fflush(stdout);
  }

  /// Ends the redrawn line on a terminal (nothing otherwise). Called again (or by the destructor) it does nothing.
  void finish() {
    if (!open_line_) return;
    std::printf("\n");
    std::fflush(stdout);
    open_line_ = false;
  }

 private:
  bool terminal_;
  bool open_line_ = false;
  int next_percent_ = 0;
};

}  // namespace vdrig::app
