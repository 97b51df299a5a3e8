#include "cli/batch_report.h"

#include <algorithm>
#include <cmath>
#include <fstream>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"

namespace mlsreg::cli {
namespace {

std::string Escape(std::string_view text) {
  std::string out;
  for (char c : text) {
    switch (c) {
      case '&':
        out += "&amp;";
        break;
      case '<':
        out += "&lt;";
        break;
      case '>':
        out += "&gt;";
        break;
      case '"':
        out += "&quot;";
        break;
      default:
        out += c;
    }
  }
  return out;
}

// A chart area in an SVG of kWidth x kHeight: data coordinates -> pixels, axes with ticks.
class Chart {
 public:
  static constexpr double kWidth = 560, kHeight = 300, kLeft = 60, kRight = 20, kTop = 20,
                          kBottom = 50;
  Chart(double x_max, double y_max) : x_max_(x_max), y_max_(y_max) {}
  double X(double x) const { return kLeft + x / x_max_ * (kWidth - kLeft - kRight); }
  double Y(double y) const { return kHeight - kBottom - y / y_max_ * (kHeight - kTop - kBottom); }

  std::string Axes(std::string_view x_label, std::string_view y_label, int x_ticks,
                   int y_ticks) const {
    std::string s = absl::StrFormat(
        "<line x1='%g' y1='%g' x2='%g' y2='%g' class='axis'/>"
        "<line x1='%g' y1='%g' x2='%g' y2='%g' class='axis'/>",
        X(0), Y(0), X(x_max_), Y(0), X(0), Y(0), X(0), Y(y_max_));
    for (int i = 0; i <= x_ticks; ++i) {
      const double x = x_max_ * i / x_ticks;
      absl::StrAppendFormat(&s, "<text x='%g' y='%g' class='tick' text-anchor='middle'>%s</text>",
                            X(x), Y(0) + 16, absl::StrFormat("%.3g", x));
    }
    for (int i = 0; i <= y_ticks; ++i) {
      const double y = y_max_ * i / y_ticks;
      absl::StrAppendFormat(&s,
                            "<line x1='%g' y1='%g' x2='%g' y2='%g' class='grid'/>"
                            "<text x='%g' y='%g' class='tick' text-anchor='end'>%s</text>",
                            X(0), Y(y), X(x_max_), Y(y), X(0) - 6, Y(y) + 4,
                            absl::StrFormat("%.3g", y));
    }
    absl::StrAppendFormat(&s, "<text x='%g' y='%g' class='label' text-anchor='middle'>%s</text>",
                          (X(0) + X(x_max_)) / 2, kHeight - 12, Escape(x_label));
    absl::StrAppendFormat(&s,
                          "<text x='14' y='%g' class='label' text-anchor='middle' "
                          "transform='rotate(-90 14 %g)'>%s</text>",
                          (Y(0) + Y(y_max_)) / 2, (Y(0) + Y(y_max_)) / 2, Escape(y_label));
    return s;
  }

  static std::string Svg(std::string_view title, const std::string& body) {
    return absl::StrFormat(
        "<svg xmlns='http://www.w3.org/2000/svg' width='%g' height='%g' viewBox='0 0 %g %g' "
        "role='img' aria-label='%s'>%s</svg>",
        kWidth, kHeight, kWidth, kHeight, Escape(title), body);
  }

 private:
  double x_max_, y_max_;
};

// Share of all jobs (failed ones count as misses) whose RMSE is below alpha, alpha in [0, 10] d.
std::string RecallSvg(const std::vector<JobOutcome>& jobs) {
  constexpr double kMaxAlpha = 10.0;
  std::vector<double> errors;
  for (const JobOutcome& j : jobs) {
    if (j.error.empty() && j.pose_error) errors.push_back(j.pose_error->rmse_d);
  }
  std::sort(errors.begin(), errors.end());
  const Chart chart(kMaxAlpha, 1.0);
  std::string points;
  for (int i = 0; i <= 200; ++i) {
    const double alpha = kMaxAlpha * i / 200;
    const double share = static_cast<double>(std::lower_bound(errors.begin(), errors.end(), alpha) -
                                             errors.begin()) /
                         static_cast<double>(jobs.size());
    absl::StrAppendFormat(&points, "%.1f,%.1f ", chart.X(alpha), chart.Y(share));
  }
  std::string body = chart.Axes("alpha (RMSE threshold, units of d)", "share of jobs", 10, 5);
  absl::StrAppendFormat(&body,
                        "<line x1='%g' y1='%g' x2='%g' y2='%g' class='threshold'/>"
                        "<text x='%g' y='%g' class='tick'>success: 5 d</text>"
                        "<polyline points='%s' class='curve'/>",
                        chart.X(5), chart.Y(0), chart.X(5), chart.Y(1), chart.X(5) + 4,
                        chart.Y(1) + 12, points);
  return Chart::Svg("alpha-recall curve", body);
}

// 1, 2, 2.5 or 5 times a power of ten, at least `v`: an axis end whose fifths are round.
double NiceCeil(double v) {
  if (!(v > 0)) return 1.0;
  const double power = std::pow(10.0, std::floor(std::log10(v)));
  for (double m : {1.0, 2.0, 2.5, 5.0, 10.0}) {
    if (m * power >= v) return m * power;
  }
  return 10.0 * power;
}

// Jobs that ran, per latency bin: 10 bins up to a round value above the slowest.
std::string LatencySvg(const std::vector<const JobOutcome*>& ran) {
  constexpr int kBins = 10;
  double slowest = 0.0;
  for (const JobOutcome* j : ran) slowest = std::max(slowest, j->seconds);
  const double x_max = NiceCeil(slowest * 1.0001);
  const double width = x_max / kBins;
  std::vector<int> counts(kBins, 0);
  for (const JobOutcome* j : ran) {
    counts[std::min(kBins - 1, static_cast<int>(j->seconds / width))]++;
  }
  const int most = *std::max_element(counts.begin(), counts.end());
  const double y_max = std::max(1.0, NiceCeil(most));
  const Chart chart(x_max, y_max);
  std::string body = chart.Axes("job time (s)", "jobs", 5, y_max < 5 ? static_cast<int>(y_max) : 5);
  for (int b = 0; b < kBins; ++b) {
    if (counts[b] == 0) continue;
    absl::StrAppendFormat(&body,
                          "<rect x='%.1f' y='%.1f' width='%.1f' height='%.1f' class='bar'>"
                          "<title>%d jobs in [%.3g, %.3g) s</title></rect>",
                          chart.X(b * width) + 1, chart.Y(counts[b]),
                          chart.X(width) - chart.X(0) - 2, chart.Y(0) - chart.Y(counts[b]),
                          counts[b], b * width, (b + 1) * width);
  }
  return Chart::Svg("latency histogram", body);
}

// Failures first, then results that did not verify or missed the ground truth, then the rest.
int Rank(const JobOutcome& j) {
  if (!j.error.empty()) return 0;
  if ((j.verified && !*j.verified) || (j.pose_error && !j.pose_error->success)) return 1;
  return 2;
}

std::string JobRow(const JobOutcome& j) {
  const char* row_class = Rank(j) == 0 ? "failed" : (Rank(j) == 1 ? "doubtful" : "ok");
  const std::string status = j.error.empty() ? "ok" : "failed";
  return absl::StrFormat(
      "<tr class='%s'><td>%s</td><td>%s</td><td>%s</td><td class='n'>%s</td><td>%s</td>"
      "<td>%s</td><td class='n'>%s</td><td>%s</td><td class='n'>%.3f</td><td class='n'>%s</td>"
      "<td class='msg'>%s</td></tr>\n",
      row_class, Escape(j.id), status, Escape(j.target_id),
      j.pose_error ? absl::StrFormat("%.3f", j.pose_error->rmse_d) : "",
      j.pose_error ? (j.pose_error->success ? "yes" : "no") : "",
      j.verified ? (*j.verified ? "yes" : "NO") : "",
      j.error.empty() ? absl::StrCat(j.iterations) : "", Escape(j.termination), j.seconds,
      j.attempts ? absl::StrCat(j.attempts) : "", Escape(j.error));
}

double Percentile(std::vector<double> values, double p) {
  if (values.empty()) return 0.0;
  std::sort(values.begin(), values.end());
  const std::size_t i = static_cast<std::size_t>(std::ceil(p * values.size())) - 1;
  return values[std::min(i, values.size() - 1)];
}

constexpr const char* kStyle = R"css(
body { font: 14px/1.4 system-ui, sans-serif; margin: 2em; color: #222; }
h1 { font-size: 1.4em; } h2 { font-size: 1.15em; margin-top: 1.6em; }
table { border-collapse: collapse; } td, th { padding: 3px 8px; border-bottom: 1px solid #ddd; }
th { text-align: left; background: #f4f4f4; } td.n { text-align: right; font-variant-numeric: tabular-nums; }
tr.failed { background: #fde8e8; } tr.doubtful { background: #fff6e0; }
td.msg { color: #a00; max-width: 40em; } .summary td:first-child { color: #555; }
.charts { display: flex; flex-wrap: wrap; gap: 2em; } figure { margin: 0; }
figcaption { max-width: 560px; font-size: 12px; color: #555; }
.axis { stroke: #333; } .grid { stroke: #e4e4e4; } .tick { font-size: 11px; fill: #444; }
.label { font-size: 12px; fill: #222; } .curve { fill: none; stroke: #1f77b4; stroke-width: 2; }
.threshold { stroke: #d62728; stroke-dasharray: 4 3; } .bar { fill: #1f77b4; }
)css";

}  // namespace

std::string BatchReportHtml(const BatchReportInfo& info, const std::vector<JobOutcome>& jobs) {
  std::vector<const JobOutcome*> order;
  for (const JobOutcome& j : jobs) order.push_back(&j);
  std::stable_sort(order.begin(), order.end(),
                   [](const JobOutcome* a, const JobOutcome* b) { return Rank(*a) < Rank(*b); });
  int failed = 0, with_truth = 0, successes = 0, not_verified = 0;
  std::vector<double> seconds;
  for (const JobOutcome& j : jobs) {
    failed += !j.error.empty();
    seconds.push_back(j.seconds);
    if (j.pose_error) {
      ++with_truth;
      successes += j.pose_error->success;
    }
    not_verified += j.verified && !*j.verified;
  }
  std::string html = absl::StrCat(
      "<!DOCTYPE html>\n<html lang='en'><head><meta charset='utf-8'>"
      "<title>mlsreg batch: ",
      Escape(info.manifest), "</title><style>", kStyle,
      "</style></head><body>\n<h1>mlsreg batch report</h1>\n<table class='summary'>");
  const auto row = [&](std::string_view key, const std::string& value) {
    absl::StrAppend(&html, "<tr><td>", std::string(key), "</td><td>", value, "</td></tr>");
  };
  row("manifest", Escape(info.manifest));
  row("server", Escape(info.server));
  row("method", Escape(info.method));
  row("jobs", absl::StrFormat("%zu: %zu ok, %d failed%s", jobs.size(), jobs.size() - failed, failed,
                              not_verified ? absl::StrFormat(", %d not verified", not_verified)
                                           : std::string()));
  if (with_truth > 0) {
    row("success (RMSE &lt; 5 d)",
        absl::StrFormat("%d of %d jobs with ground truth", successes, with_truth));
  }
  row("job time",
      absl::StrFormat("median %.3f s, p95 %.3f s, max %.3f s (concurrency %d, wall %.1f s)",
                      Percentile(seconds, 0.5), Percentile(seconds, 0.95), Percentile(seconds, 1.0),
                      info.concurrency, info.wall_seconds));
  html += "</table>\n";
  if (failed > 0) {
    html += "<h2>Failures</h2>\n<table><tr><th>job</th><th>target</th><th>error</th></tr>\n";
    for (const JobOutcome* j : order) {
      if (j->error.empty()) break;
      absl::StrAppend(&html, "<tr class='failed'><td>", Escape(j->id), "</td><td>",
                      Escape(j->target_id), "</td><td class='msg'>", Escape(j->error),
                      "</td></tr>\n");
    }
    html += "</table>\n";
  }
  html += "<h2>Charts</h2>\n<div class='charts'>";
  if (with_truth > 0) {
    absl::StrAppend(&html, "<figure>", RecallSvg(jobs),
                    "<figcaption>alpha-recall: share of all jobs with RMSE below alpha against "
                    "the ground truth (failed jobs count as misses)</figcaption></figure>");
  }
  std::vector<const JobOutcome*> ran;  // reached a server: a result, or an error after a call
  for (const JobOutcome& j : jobs) {
    if (j.error.empty() || j.attempts > 0 || !j.request_id.empty()) ran.push_back(&j);
  }
  if (!ran.empty()) {
    absl::StrAppend(&html, "<figure>", LatencySvg(ran),
                    "<figcaption>latency of the jobs that ran (the registration round trip, "
                    "retries included)</figcaption></figure>");
  }
  html +=
      "</div>\n<h2>Jobs</h2>\n<table><tr><th>job</th><th>status</th><th>target</th>"
      "<th>RMSE/d</th><th>success</th><th>verified</th><th>iterations</th><th>termination</th>"
      "<th>time (s)</th><th>attempts</th><th>error</th></tr>\n";
  for (const JobOutcome* j : order) html += JobRow(*j);
  html += "</table>\n</body></html>\n";
  return html;
}

absl::Status WriteBatchReport(const std::string& path, const BatchReportInfo& info,
                              const std::vector<JobOutcome>& jobs) {
  std::ofstream out(path, std::ios::binary);
  out << BatchReportHtml(info, jobs);
  if (!out) return absl::UnavailableError(absl::StrCat("--report: cannot write '", path, "'"));
  return absl::OkStatus();
}

}  // namespace mlsreg::cli
