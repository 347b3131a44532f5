// Feedback traces (sim/trace/feedback_trace.h), the input of `vtsim replay --feedback`. An
// accepted file must write back, frame by frame, to a file that reads as the same frames.
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <sstream>
#include <string>

#include "fuzz_targets.h"
#include "sim/trace/feedback_trace.h"

namespace vtsim::fuzz {

void feedback(const std::uint8_t* data, std::size_t size) {
  FeedbackHeader h;
  std::vector<FeedbackFrame> frames;
  bool accepted = false;
  expect_accept_or_reject("feedback", [&] {
    FeedbackReader r(std::make_unique<std::istringstream>(std::string(reinterpret_cast<const char*>(data), size)), "fuzz");
    h = r.header();
    FeedbackFrame f;
    while (r.next(f)) frames.push_back(f);
    accepted = true;
  });
  if (!accepted) return;
  must_succeed("feedback", "round trip", [&] {
    const std::string out = input_file(nullptr, 0, "vtfb");
    {
      FeedbackWriter w(out, h);
      for (const FeedbackFrame& f : frames) w.add(f);
      w.finish();
    }
    FeedbackReader r(out);
    FeedbackFrame f;
    for (const FeedbackFrame& want : frames) {
      if (!r.next(f) || f.tiles != want.tiles || f.t_s != want.t_s || f.fresh != want.fresh) {
        std::fprintf(stderr, "vtsim fuzz feedback: the round trip changed a frame\n");
        std::abort();
      }
    }
    if (r.next(f)) {
      std::fprintf(stderr, "vtsim fuzz feedback: the round trip added a frame\n");
      std::abort();
    }
  });
}

}  // namespace vtsim::fuzz
