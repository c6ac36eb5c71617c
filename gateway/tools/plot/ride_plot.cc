#include "gateway/tools/plot/ride_plot.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <type_traits>

#include "gateway/common/untrusted_text.h"
#include "gateway/tools/common/time_arg.h"
#include "gateway/tools/plot/ride_plot_map.h"

namespace fleetgw::tools {
namespace ride_svg {
namespace {

// Layout, in user units (= CSS pixels at the document's size).
constexpr double kTitleY = 30;
constexpr double kSubtitleY = 52;
constexpr double kPanelsTop = 80;
constexpr double kPanelsBottom = 636;
constexpr double kPanelGap = 24;
constexpr int kPanelCount = 4;
constexpr double kPanelHeight =
    (kPanelsBottom - kPanelsTop - (kPanelCount - 1) * kPanelGap) / kPanelCount;
constexpr double kPlotWidth = kAxisRight - kAxisLeft;
constexpr double kHeadroom = 6;  // the top of a panel's value range sits this far below its top
constexpr int kMaxTicks = 20;    // bounds the tick loops whatever the values
constexpr std::string_view kAxisColour = "#222222";
constexpr std::string_view kGridColour = "#e2e2e2";
constexpr std::string_view kTextColour = "#333333";

struct Pt {
  double x = 0;
  double y = 0;
};

// A value range with "nice" tick steps (1, 2 or 5 times a power of ten).
struct Scale {
  double lo = 0;
  double hi = 1;
  double step = 1;
};

double nice_step(double span, int target) {
  if (!(span > 0) || !std::isfinite(span)) return 1;
  const double raw = span / target;
  const double mag = std::pow(10.0, std::floor(std::log10(raw)));
  const double f = raw / mag;
  return (f <= 1 ? 1 : f <= 2 ? 2 : f <= 5 ? 5 : 10) * mag;
}

Scale nice_scale(double lo, double hi, int target) {
  if (!(hi > lo)) hi = lo + 1;
  const double step = nice_step(hi - lo, target);
  return {std::floor(lo / step + 1e-9) * step, std::ceil(hi / step - 1e-9) * step, step};
}

int decimals_for(double step) {
  if (step >= 1) return 0;
  return static_cast<int>(std::ceil(-std::log10(step) - 1e-9));
}

std::string num(double v, int decimals = 1) {
  if (std::fabs(v) < 1e-9 || !std::isfinite(v)) v = 0;  // never "-0.0" or "nan"
  return fmt::format("{:.{}f}", v, decimals);
}

std::string duration_text(double seconds) {
  if (!(seconds > 0)) return "0 min";
  if (seconds < 3600) return num(seconds / 60.0, 1) + " min";
  const auto minutes = static_cast<long long>(std::llround(seconds / 60.0));
  return fmt::format("{} h {:02} min", minutes / 60, minutes % 60);
}

std::string assist_label(int level, const std::vector<std::pair<int, std::string>>& names) {
  for (const auto& [value, name] : names) {
    if (value == level) return name;
  }
  return level >= 0 && level <= 0xff ? fmt::format("0x{:02X}", level) : std::to_string(level);
}

// Keeps, per pixel column, the first, last, lowest and highest point (in time order).
std::vector<Pt> thin(const std::vector<Pt>& in) {
  if (in.size() <= static_cast<std::size_t>(2 * kPlotWidth)) return in;
  std::vector<Pt> out;
  std::size_t i = 0;
  while (i < in.size()) {
    const double column = std::floor(in[i].x);
    std::size_t j = i;
    std::size_t lo = i, hi = i;
    while (j < in.size() && std::floor(in[j].x) == column) {
      if (in[j].y < in[lo].y) lo = j;
      if (in[j].y > in[hi].y) hi = j;
      ++j;
    }
    std::size_t keep[] = {i, lo, hi, j - 1};
    std::sort(std::begin(keep), std::end(keep));
    for (std::size_t k = 0; k < 4; ++k) {
      if (k == 0 || keep[k] != keep[k - 1]) out.push_back(in[keep[k]]);
    }
    i = j;
  }
  return out;
}

class Builder {
 public:
  explicit Builder(const RidePlot& plot) : plot_(plot) {
    double t_max = plot.duration_s;
    for (const auto& s : plot.samples) {
      if (std::isfinite(s.t_s)) t_max = std::max(t_max, s.t_s);
    }
    t_max_min_ = t_max > 0 && std::isfinite(t_max) ? t_max / 60.0 : 1.0;
  }

  std::string build() {
    // The map first: whether there is one decides the document's height.
    const auto map = map_panel_svg(plot_, kSvgHeight);
    const int height = kSvgHeight + (map ? kMapPanelHeight : 0);
    out_ += "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n";
    out_ += fmt::format(
        "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{0}\" height=\"{1}\" "
        "viewBox=\"0 0 {0} {1}\" font-family=\"DejaVu Sans, Liberation Sans, Arial, "
        "sans-serif\" fill=\"{2}\">\n",
        kSvgWidth, height, kTextColour);
    const std::string id = xml_text(plot_.ride_id);
    out_ += "<title>Ride " + id + "</title>\n";
    out_ += fmt::format("<rect width=\"{}\" height=\"{}\" fill=\"#ffffff\"/>\n", kSvgWidth, height);
    out_ += fmt::format(
        "<text class=\"title\" x=\"{}\" y=\"{}\" font-size=\"18\" font-weight=\"bold\">Ride "
        "{}</text>\n",
        kAxisLeft, kTitleY, id);
    std::string sub = xml_text(iso_utc(plot_.start_us));
    sub += plot_.distance_km && std::isfinite(*plot_.distance_km)
               ? " \u00b7 " + num(*plot_.distance_km, 2) + " km"
               : " \u00b7 distance unknown";
    sub += " \u00b7 " + duration_text(plot_.duration_s);
    if (plot_.open) sub += " \u00b7 still open";
    sub += fmt::format(" \u00b7 {} samples", plot_.samples.size());
    out_ += fmt::format("<text class=\"subtitle\" x=\"{}\" y=\"{}\" font-size=\"13\">{}</text>\n",
                        kAxisLeft, kSubtitleY, sub);

    line_panel(0, "speed", "speed km/h", "#1f77b4",
               [](const PlotSample& s) { return s.speed_kmh; });
    line_panel(1, "power", "power W", "#d62728", [](const PlotSample& s) { return s.power_w; });
    line_panel(2, "soc", "SOC %", "#2ca02c", [](const PlotSample& s) { return s.soc_pct; });
    assist_panel(3);
    out_ += fmt::format(
        "<text class=\"xlabel\" x=\"{}\" y=\"{}\" font-size=\"12\" text-anchor=\"middle\">"
        "minutes from ride start</text>\n",
        num(kAxisLeft + kPlotWidth / 2), num(kPanelsBottom + 40));
    out_ += map ? *map : no_track_note(kPanelsBottom + 56);
    out_ += "</svg>\n";
    return std::move(out_);
  }

 private:
  using Getter = std::function<std::optional<double>(const PlotSample&)>;

  static double top_of(int panel) { return kPanelsTop + panel * (kPanelHeight + kPanelGap); }
  static double bottom_of(int panel) { return top_of(panel) + kPanelHeight; }
  double x_of(double t_s) const { return kAxisLeft + (t_s / 60.0) / t_max_min_ * kPlotWidth; }

  // Runs of consecutive present values no more than gap_s apart.
  template <typename Value, typename Get>
  std::vector<std::vector<std::pair<double, Value>>> runs(const Get& get) const {
    std::vector<std::vector<std::pair<double, Value>>> out;
    std::vector<std::pair<double, Value>> run;
    for (const auto& s : plot_.samples) {
      const auto v = get(s);
      bool ok = v.has_value();
      if constexpr (std::is_floating_point_v<Value>) ok = ok && std::isfinite(*v);
      if (!ok || !std::isfinite(s.t_s)) {
        if (!run.empty()) out.push_back(std::move(run));
        run.clear();
        continue;
      }
      if (!run.empty() && s.t_s - run.back().first > plot_.gap_s) {
        out.push_back(std::move(run));
        run.clear();
      }
      run.emplace_back(s.t_s, *v);
    }
    if (!run.empty()) out.push_back(std::move(run));
    return out;
  }

  void open_panel(int panel, std::string_view name, std::string_view label,
                  std::string_view colour) {
    out_ += fmt::format("<g class=\"panel\" id=\"panel-{}\">\n", name);
    out_ += fmt::format(
        "<text class=\"panel-label\" x=\"{}\" y=\"{}\" font-size=\"12\" font-weight=\"bold\" "
        "fill=\"{}\">{}</text>\n",
        kAxisLeft + 4, num(top_of(panel) - 6), colour, label);
    // Vertical grid and time ticks, labels under the last panel only.
    const double step = nice_step(t_max_min_, 8);
    const int decimals = decimals_for(step);
    for (int k = 0; k <= kMaxTicks && k * step <= t_max_min_ * (1 + 1e-9); ++k) {
      const double x = x_of(k * step * 60.0);
      const double bottom = bottom_of(panel);
      if (k > 0) grid(x, top_of(panel), x, bottom);
      out_ += fmt::format(
          "<line x1=\"{0}\" y1=\"{1}\" x2=\"{0}\" y2=\"{2}\" stroke=\"{3}\" stroke-width=\"1\"/>\n",
          num(x), num(bottom), num(bottom + 5), kAxisColour);
      if (panel == kPanelCount - 1) {
        out_ += fmt::format(
            "<text x=\"{}\" y=\"{}\" font-size=\"11\" text-anchor=\"middle\">{}</text>\n", num(x),
            num(bottom + 18), num(k * step, decimals));
      }
    }
  }

  void grid(double x1, double y1, double x2, double y2) {
    out_ += fmt::format(
        "<line class=\"grid\" x1=\"{}\" y1=\"{}\" x2=\"{}\" y2=\"{}\" stroke=\"{}\" "
        "stroke-width=\"1\"/>\n",
        num(x1), num(y1), num(x2), num(y2), kGridColour);
  }

  void y_tick(int panel, double y, const std::string& label) {
    if (y < top_of(panel) + kHeadroom - 0.5) return;
    if (y < bottom_of(panel) - 0.5) grid(kAxisLeft, y, kAxisRight, y);
    out_ += fmt::format(
        "<line x1=\"{0}\" y1=\"{1}\" x2=\"{2}\" y2=\"{1}\" stroke=\"{3}\" stroke-width=\"1\"/>\n",
        kAxisLeft - 5, num(y), kAxisLeft, kAxisColour);
    out_ += fmt::format("<text x=\"{}\" y=\"{}\" font-size=\"11\" text-anchor=\"end\">{}</text>\n",
                        kAxisLeft - 8, num(y + 4), label);
  }

  void close_panel(int panel, bool has_data) {
    const double top = top_of(panel), bottom = bottom_of(panel);
    if (!has_data) {
      out_ += fmt::format(
          "<text class=\"no-data\" x=\"{}\" y=\"{}\" font-size=\"13\" text-anchor=\"middle\" "
          "fill=\"#888888\">no data</text>\n",
          num(kAxisLeft + kPlotWidth / 2), num((top + bottom) / 2 + 4));
    }
    // The axes last, over the grid and the data.
    out_ += fmt::format(
        "<line class=\"axis axis-y\" x1=\"{0}\" y1=\"{1}\" x2=\"{0}\" y2=\"{2}\" stroke=\"{3}\" "
        "stroke-width=\"2\" shape-rendering=\"crispEdges\"/>\n",
        kAxisLeft, num(top), num(bottom), kAxisColour);
    out_ += fmt::format(
        "<line class=\"axis axis-x\" x1=\"{0}\" y1=\"{1}\" x2=\"{2}\" y2=\"{1}\" stroke=\"{3}\" "
        "stroke-width=\"2\" shape-rendering=\"crispEdges\"/>\n",
        kAxisLeft, num(bottom), kAxisRight, kAxisColour);
    out_ += "</g>\n";
  }

  void series_path(std::string_view name, std::string_view colour, const std::string& d,
                   const std::vector<Pt>& dots) {
    if (!d.empty()) {
      out_ += fmt::format(
          "<path class=\"series series-{}\" fill=\"none\" stroke=\"{}\" stroke-width=\"1.5\" "
          "stroke-linejoin=\"round\" d=\"{}\"/>\n",
          name, colour, d);
    }
    for (const auto& p : dots) {
      out_ +=
          fmt::format("<circle class=\"dot dot-{}\" cx=\"{}\" cy=\"{}\" r=\"2\" fill=\"{}\"/>\n",
                      name, num(p.x), num(p.y), colour);
    }
  }

  void line_panel(int panel, std::string_view name, std::string_view label, std::string_view colour,
                  const Getter& get) {
    const auto data = runs<double>(get);
    double lo = 0, hi = 0;
    bool first = true;
    for (const auto& run : data) {
      for (const auto& [t, v] : run) {
        lo = first ? v : std::min(lo, v);
        hi = first ? v : std::max(hi, v);
        first = false;
      }
    }
    Scale scale;
    if (name == "soc") {
      scale = nice_scale(std::max(0.0, std::min(lo, hi - 10) - 2), std::min(100.0, hi + 2), 4);
      scale.lo = std::max(0.0, scale.lo);
      scale.hi = std::min(std::max(100.0, hi), scale.hi);
    } else {
      scale = nice_scale(std::min(0.0, lo), std::max(hi, name == "speed" ? 5.0 : 50.0), 4);
    }
    const double top = top_of(panel) + kHeadroom, bottom = bottom_of(panel);
    const auto y_of = [&](double v) {
      return bottom - (v - scale.lo) / (scale.hi - scale.lo) * (bottom - top);
    };
    open_panel(panel, name, label, colour);
    const int decimals = decimals_for(scale.step);
    for (int k = 0; k <= kMaxTicks && scale.lo + k * scale.step <= scale.hi + scale.step * 1e-9;
         ++k) {
      const double v = scale.lo + k * scale.step;
      y_tick(panel, y_of(v), num(v, decimals));
    }
    std::string d;
    std::vector<Pt> dots;
    for (const auto& run : data) {
      std::vector<Pt> pts;
      pts.reserve(run.size());
      for (const auto& [t, v] : run) pts.push_back({x_of(t), y_of(v)});
      if (pts.size() == 1) {
        dots.push_back(pts.front());
        continue;
      }
      pts = thin(pts);
      d += d.empty() ? "M" : " M";
      for (std::size_t i = 0; i < pts.size(); ++i) {
        d += (i == 0 ? "" : " ") + num(pts[i].x) + "," + num(pts[i].y);
      }
    }
    series_path(name, colour, d, dots);
    close_panel(panel, !data.empty());
  }

  // Assist levels as steps: each level holds until the next sample of its run; the last one
  // to the end of the ride when that is within gap_s.
  void assist_panel(int panel) {
    constexpr std::string_view kColour = "#9467bd";
    const auto data = runs<int>([](const PlotSample& s) { return s.assist_level; });
    std::vector<int> levels;
    for (const auto& run : data) {
      for (const auto& [t, v] : run) levels.push_back(v);
    }
    std::sort(levels.begin(), levels.end());
    levels.erase(std::unique(levels.begin(), levels.end()), levels.end());
    const double top = top_of(panel) + kHeadroom, bottom = bottom_of(panel);
    const auto y_of = [&](int level) {
      const auto i = std::lower_bound(levels.begin(), levels.end(), level) - levels.begin();
      return bottom -
             (static_cast<double>(i) + 0.5) / static_cast<double>(levels.size()) * (bottom - top);
    };
    open_panel(panel, "assist", "assist level", kColour);
    const std::size_t every = levels.size() / 8 + 1;  // at most 8 labels
    for (std::size_t i = 0; i < levels.size(); i += every) {
      y_tick(panel, y_of(levels[i]), xml_text(assist_label(levels[i], plot_.assist_names)));
    }
    std::string d;
    std::vector<Pt> dots;
    const double t_end = t_max_min_ * 60.0;
    for (const auto& run : data) {
      const double last_t = run.back().first;
      const double hold_to = t_end - last_t <= plot_.gap_s ? t_end : last_t;
      if (run.size() == 1 && hold_to == last_t) {
        dots.push_back({x_of(last_t), y_of(run.front().second)});
        continue;
      }
      d += (d.empty() ? "M" : " M") + num(x_of(run.front().first)) + "," +
           num(y_of(run.front().second));
      int current = run.front().second;
      for (const auto& [t, level] : run) {
        if (level == current) continue;
        d += " H" + num(x_of(t)) + " V" + num(y_of(level));
        current = level;
      }
      d += " H" + num(x_of(hold_to));
    }
    series_path("assist", kColour, d, dots);
    close_panel(panel, !data.empty());
  }

  const RidePlot& plot_;
  double t_max_min_ = 1;
  std::string out_;
};

}  // namespace
}  // namespace ride_svg

std::string xml_text(std::string_view text) {
  const std::string printable = common::escape_controls(text);
  std::string out;
  out.reserve(printable.size());
  for (std::size_t i = 0; i < printable.size(); ++i) {
    const char c = printable[i];
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
      case '\'':
        out += "&apos;";
        break;
      default:
        // U+FFFE and U+FFFF are not XML characters: U+FFFD instead.
        if (c == '\xEF' && i + 2 < printable.size() && printable[i + 1] == '\xBF' &&
            (printable[i + 2] == '\xBE' || printable[i + 2] == '\xBF')) {
          out += "\xEF\xBF\xBD";
          i += 2;
        } else {
          out += c;
        }
    }
  }
  return out;
}

double gap_threshold_s(const std::vector<PlotSample>& samples) {
  std::vector<double> steps;
  for (std::size_t i = 1; i < samples.size(); ++i) {
    const double dt = samples[i].t_s - samples[i - 1].t_s;
    if (dt > 0 && std::isfinite(dt)) steps.push_back(dt);
  }
  if (steps.empty()) return 5.0;
  const auto mid = steps.begin() + static_cast<std::ptrdiff_t>(steps.size() / 2);
  std::nth_element(steps.begin(), mid, steps.end());
  return std::max(5.0, 3.0 * *mid);
}

std::string render_ride_svg(const RidePlot& plot) {
  return ride_svg::Builder(plot).build();
}

}  // namespace fleetgw::tools
