// reenact-mirror's command line (the thin main calls RunMirror). Usage:
//
//   reenact-mirror (--teacher ID --server HOST:PORT [--cache DIR]
//                   | --teacher-file FILE.reen|DIR [--teacher ID])
//                  (--learner-take FILE.mcap | --daemon HOST:PORT) [--sensor ID]
//                  [--layout side|ghost] [--ghost-alpha A] [--width W] [--height H]
//                  [--render-to DIR [--every N] [--no-mp4]] [--report DIR]
//                  [--repetitions N] [--hold-s S] [--tolerance-deg D] [--dtw]
//                  [--speed X] [--challenge cycle|hardest [--views DEG,...]]
//                  [--seconds S] [--mode vdtm|baked] [--msaa 0|2|4|8] [--fixed-camera]
//                  [--no-hud] [--json]
//
// Without --render-to it opens a window (Esc or Q quits).
// Exit codes: 0 done, 1 failure (teacher, learner, GL, files), 2 usage.
#pragma once

#include <iosfwd>
#include <string>
#include <vector>

namespace reenact::mirror {

extern const char kMirrorUsage[];

// Runs the mirror with `args` (argv without the program name); messages go
// to `err`, the --json summary to `out`. Returns the exit code.
int RunMirror(const std::vector<std::string>& args, std::ostream& out, std::ostream& err);

}  // namespace reenact::mirror
