// vdrig report (pipeline/report.hpp): a session with missing parts, a damaged session, and the page loaded in a real
// browser (Debian's chromium, headless), which must show every section, decode every image, log nothing to its
// console and fetch nothing.
#include <gtest/gtest.h>

#include <cctype>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "small_session.hpp"
#include "vdrig/core/file_write.hpp"
#include "vdrig/pipeline/pipeline.hpp"
#include "vdrig/pipeline/report.hpp"
#include "vdrig/test/process.hpp"
#include "vdrig/test/temp_dir.hpp"

namespace vdrig::pipeline {
namespace {
namespace fs = std::filesystem;

const char* const kSections[] = {"coverage", "views", "calibration", "maps", "compare", "texels", "provenance"};

/// The text of <section id="id"> ... </section>.
std::string section_of(const std::string& html, const std::string& id) {
  const auto start = html.find("<section id=\"" + id + "\">");
  if (start == std::string::npos) return "";
  return html.substr(start, html.find("</section>", start) - start);
}

class Report : public ::testing::Test {
 protected:
  const ::vdrig::test::TempDir dir_{"report"};
};

TEST_F(Report, SessionWithMissingPartsShowsWhatIsThereAndNamesWhatIsMissing) {
  auto session = test::small_merged_session(dir_ / "session");
  ASSERT_TRUE(session) << session.error().describe();
  fs::remove(session->layout().camera_file());  // the geometric calibration is one of the missing parts
  fs::remove(session->layout().views_file());
  auto html = build_report_html(dir_ / "session");
  ASSERT_TRUE(html) << html.error().describe();
  for (const char* id : kSections) EXPECT_NE(section_of(*html, id), "") << id;
  EXPECT_NE(section_of(*html, "coverage").find("<circle"), std::string::npos) << "the directions are plotted";
  EXPECT_EQ(section_of(*html, "coverage").find("Missing"), std::string::npos) << "every view was captured";
  for (const char* id : {"calibration", "maps", "compare", "texels"})
    EXPECT_NE(section_of(*html, id).find("Missing:"), std::string::npos) << id;
  EXPECT_NE(section_of(*html, "maps").find("vdrig fit"), std::string::npos) << "names the command that makes it";
  EXPECT_EQ(html->find("http://"), std::string::npos);
  EXPECT_EQ(html->find("https://"), std::string::npos);

  // A damaged map is reported in its section; the rest of the page is still there.
  fs::create_directories(session->layout().maps_dir());
  ASSERT_TRUE(write_file_atomic(session->layout().parameter_map_file("phong:1"), "not an EXR"));
  auto damaged = build_report_html(dir_ / "session");
  ASSERT_TRUE(damaged) << damaged.error().describe();
  EXPECT_NE(section_of(*damaged, "maps").find("Missing: a readable map"), std::string::npos);
  EXPECT_NE(section_of(*damaged, "texels").find("Missing: a readable fitted map"), std::string::npos);
  EXPECT_NE(section_of(*damaged, "coverage").find("<circle"), std::string::npos);
}

// What a reader sees: dashes written once (a literal "&#8211;" showed where &#8211; was escaped twice), numbers to a
// few significant digits (no "2.2193484540451628e-05"), a colour bar from 0 where its minimum is 0 at the scale shown
// (not "2.201e-17"), and fit timings the fit recorded rather than the span of the maps' write times.
TEST_F(Report, DashesOnceNumbersReadableTimingsRecorded) {
  auto session = test::small_merged_session(dir_ / "session");
  ASSERT_TRUE(session) << session.error().describe();
  const double w = session->manifest().surface_width_mm, h = session->manifest().surface_height_mm;
  fitting::ParameterMap old_map(fitting::parse_model("phong:1").value(), 8, 8, w, h);  // no held-out views
  fitting::ParameterMap timed(fitting::parse_model("phong:1").value(), 8, 8, w, h);
  for (int t = 0; t < 8; ++t)
    for (int s = 0; s < 8; ++s)
      for (const char* c : {"rms.R", "rms.G", "rms.B"})
        timed.at(c, s, t) = s + t == 0 ? 2.201e-17f : 0.04f * (s + 1) / 8;
  timed.image().number_attributes[fitting::kFitSecondsAttribute] = 51.0437;
  fs::create_directories(session->layout().maps_dir());
  ASSERT_TRUE(old_map.write(session->layout().parameter_map_file("old")));
  ASSERT_TRUE(timed.write(session->layout().parameter_map_file("timed")));

  auto html = build_report_html(dir_ / "session");
  ASSERT_TRUE(html) << html.error().describe();
  EXPECT_EQ(html->find("&amp;#"), std::string::npos) << "an entity escaped twice";
  EXPECT_NE(section_of(*html, "maps").find("held-out views: &#8211;"), std::string::npos) << section_of(*html, "maps");
  EXPECT_EQ(html->find("e-17"), std::string::npos) << "the colour bar's minimum is 0 at its scale";
  const std::string provenance = section_of(*html, "provenance");
  EXPECT_NE(provenance.find("<td>51</td>"), std::string::npos) << provenance;
  EXPECT_NE(provenance.find("not recorded (an older map)"), std::string::npos) << provenance;
  // No number printed with more digits than anyone reads (a raw double has 15 to 17); inline images left out.
  std::string text = *html;
  for (size_t at = text.find("base64,"); at != std::string::npos; at = text.find("base64,", at))
    text.erase(at, text.find('"', at) - at);
  // A digit, a point and nine or more digits (no std::regex: GCC 12's fails the ASan build, -Wmaybe-uninitialized).
  std::string raw;
  for (size_t at = text.find('.'); at != std::string::npos && raw.empty(); at = text.find('.', at + 1)) {
    size_t digits = 0;
    while (at + 1 + digits < text.size() && std::isdigit(static_cast<unsigned char>(text[at + 1 + digits]))) ++digits;
    if (at > 0 && std::isdigit(static_cast<unsigned char>(text[at - 1])) && digits >= 9)
      raw = text.substr(at - 1, digits + 2);
  }
  EXPECT_TRUE(raw.empty()) << "a raw number: " << raw;
}

TEST_F(Report, DamagedSessionIsAClearError) {
  auto session = test::small_merged_session(dir_ / "session");
  ASSERT_TRUE(session);
  ASSERT_TRUE(write_file_atomic(session->layout().manifest_file(), "{ not json"));
  auto html = build_report_html(dir_ / "session");
  ASSERT_FALSE(html);
  EXPECT_NE(html.error().message.find("cannot read session"), std::string::npos) << html.error().message;
  EXPECT_FALSE(build_report_html(dir_ / "nowhere"));

#ifdef VDRIG_CLI_PATH
  const auto r = vdrig::test::run_vdrig("report " + vdrig::test::shell_quote((dir_ / "session").string()) + " --out " +
                                        vdrig::test::shell_quote((dir_ / "r.html").string()));
  EXPECT_TRUE(r.exit_code != 0 && r.signal == 0 && !r.timed_out) << "exit " << r.exit_code;
  const std::string& message = r.err;
  EXPECT_EQ(std::count(message.begin(), message.end(), '\n'), 1) << "one line: " << message;
  EXPECT_NE(message.find("manifest"), std::string::npos) << message;
  EXPECT_FALSE(fs::exists(dir_ / "r.html"));
#endif
}

/// Debian's chromium, or empty when not installed.
std::string find_chromium() {
  for (const char* candidate : {"/usr/bin/chromium", "/usr/bin/chromium-browser"})
    if (fs::exists(candidate)) return candidate;
  return "";
}

/// Checks run inside the page once it has loaded: every section present, every <img> decoded, no error event, no
/// console.error, no fetched resource and no src/href other than inline data: URIs and in-page anchors. The verdict is
/// written into the DOM as JSON, which --dump-dom prints.
constexpr const char* kCheckScript = R"(<script>
window.vdrigProblems = [];
window.addEventListener('error', e => vdrigProblems.push('error event: ' + (e.message || (e.target && e.target.outerHTML
  ? e.target.outerHTML.slice(0, 80) : '?'))), true);
const vdrigConsoleError = console.error;
console.error = (...args) => {
  vdrigProblems.push('console.error: ' + args.join(' '));
  vdrigConsoleError.apply(console, args);
};
window.addEventListener('load', () => {
  const problems = vdrigProblems.slice();
  for (const img of document.images)
    if (!img.complete || img.naturalWidth === 0) problems.push('image not decoded: ' + img.alt);
  for (const id of SECTIONS)
    if (!document.querySelector('section#' + id)) problems.push('missing section ' + id);
  for (const r of performance.getEntriesByType('resource')) problems.push('fetched: ' + r.name);
  // Nothing runs off the page at the window's width (1280 px): long cells wrap, wide tables scroll inside it.
  const width = document.documentElement.scrollWidth;
  if (width > window.innerWidth) problems.push('wider than the window: ' + width + ' px > ' + window.innerWidth + ' px');
  for (const e of document.querySelectorAll('[src], [href]')) {
    const url = e.getAttribute('src') || e.getAttribute('href');
    if (!url.startsWith('data:') && !url.startsWith('#')) problems.push('external reference: ' + url);
  }
  const pre = document.createElement('pre');
  pre.id = 'vdrig-check';
  pre.textContent = JSON.stringify({problems: problems, images: document.images.length,
                                    svgs: document.querySelectorAll('svg').length});
  document.body.appendChild(pre);
});
</script>)";

struct BrowserVerdict {
  bool ran = false;
  std::string failure;  // why it did not run
  nlohmann::json problems = nlohmann::json::array();
  int images = 0, svgs = 0;
  std::string console_lines;  // chromium's log lines of console messages (any level)
};

/// Loads `html` (written to DIR/page.html with kCheckScript injected at the top of <head>) in headless chromium and
/// reads the verdict back from the dumped DOM.
BrowserVerdict load_in_browser(const std::string& chromium, const std::string& html, const fs::path& dir) {
  BrowserVerdict verdict;
  std::string sections = "[";
  for (const char* id : kSections) sections += std::string(sections.size() > 1 ? "," : "") + "'" + id + "'";
  std::string script = kCheckScript;
  script.replace(script.find("SECTIONS"), 8, sections + "]");
  std::string checked = html;
  const auto head = checked.find("<head>");
  if (head == std::string::npos) return verdict.failure = "no <head>", verdict;
  checked.insert(head + 6, script);
  const fs::path page = dir / "page.html";
  if (!write_file_atomic(page, checked)) return verdict.failure = "cannot write " + page.string(), verdict;
  // Headless chromium as root needs --no-sandbox; its own profile folder keeps it away from $HOME.
  const std::vector<std::string> argv = {chromium,
                                         "--headless",
                                         "--no-sandbox",
                                         "--disable-gpu",
                                         "--no-first-run",
                                         "--user-data-dir=" + (dir / "profile").string(),
                                         "--enable-logging=stderr",
                                         "--v=0",
                                         "--virtual-time-budget=5000",
                                         "--window-size=1280,1024",  // the width the issue read the report at
                                         "--dump-dom",
                                         "file://" + fs::absolute(page).string()};
  const vdrig::test::ProcessRun run = vdrig::test::run_process(argv, {60});
  const std::string& out = run.out;  // the DOM; chromium's log is run.err
  if (run.exit_code != 0) {
    verdict.failure = "chromium exited " + std::to_string(run.exit_code) + ":";
    for (const auto& a : argv) verdict.failure += " " + a;
    return verdict.failure += "\n" + run.err, verdict;
  }
  const std::string open = "<pre id=\"vdrig-check\">";
  const auto start = out.find(open);
  if (start == std::string::npos)
    return verdict.failure = "the checks did not run:\n" + out.substr(0, 2000) + run.err, verdict;
  std::string text = out.substr(start + open.size(), out.find("</pre>", start) - start - open.size());
  for (const auto& [entity, plain] : {std::pair{"&lt;", "<"}, std::pair{"&gt;", ">"}, std::pair{"&amp;", "&"}})
    for (size_t at = text.find(entity); at != std::string::npos; at = text.find(entity, at + 1))
      text.replace(at, std::string(entity).size(), plain);
  const auto result = nlohmann::json::parse(text, nullptr, false);
  if (result.is_discarded()) return verdict.failure = "unreadable verdict: " + text, verdict;
  verdict.ran = true;
  verdict.problems = result["problems"];
  verdict.images = result["images"].get<int>();
  verdict.svgs = result["svgs"].get<int>();
  // Console messages of any level appear in chromium's log as "CONSOLE" lines; the report has no script of its own.
  std::istringstream lines(run.err);
  for (std::string line; std::getline(lines, line);)
    if (line.find(":CONSOLE") != std::string::npos) verdict.console_lines += line + "\n";
  return verdict;
}

TEST_F(Report, LoadsInARealBrowserWithoutErrors) {
  const std::string chromium = find_chromium();
  if (chromium.empty()) GTEST_SKIP() << "chromium is not installed (scripts/setup installs it)";

  // A session with every part the report shows: a fit with a held-out view, its observation map, a comparison.
  auto session = test::small_merged_session(dir_ / "session");
  ASSERT_TRUE(session) << session.error().describe();
  const int n = static_cast<int>(session->manifest().views.size());
  auto obs_file = session_obsmap_file(session.value(), 8, 8);
  ASSERT_TRUE(obs_file) << obs_file.error().describe();
  auto obs = fitting::ObsMapReader::open(obs_file.value());
  ASSERT_TRUE(obs);
  fitting::MapFitOptions fit;
  fit.held_out = spread_holdout_views(n, 1);
  auto map = fitting::fit_parameter_map(obs.value(), fit);
  ASSERT_TRUE(map) << map.error().describe();
  const fs::path map_path = session->layout().parameter_map_file("phong:1");
  fs::create_directories(map_path.parent_path());
  ASSERT_TRUE(map->write(map_path));
  auto compared = compare_maps(session.value(), {map_path}, fit.held_out);
  if (!compared && compared.error().code == ErrorCode::kUnsupported)
    GTEST_SKIP() << "no OpenGL display for the comparison: " << compared.error().message;
  ASSERT_TRUE(compared) << compared.error().describe();

  ReportOptions options;
  options.texels = {{3, 4}};
  auto html = build_report_html(dir_ / "session", options);
  ASSERT_TRUE(html) << html.error().describe();
  for (const char* id : {"calibration", "maps", "compare", "texels"})
    EXPECT_EQ(section_of(*html, id).find("Missing:"), std::string::npos) << id << ": " << section_of(*html, id);

  const BrowserVerdict verdict = load_in_browser(chromium, html.value(), dir_);
  ASSERT_TRUE(verdict.ran) << verdict.failure;
  EXPECT_TRUE(verdict.problems.empty()) << verdict.problems.dump(2);
  EXPECT_GE(verdict.images, 4 + 2) << "compare thumbnails and false-colour maps";
  EXPECT_GE(verdict.svgs, 4) << "polar plots and colour bars";
  EXPECT_TRUE(verdict.console_lines.empty()) << verdict.console_lines;
}

// The browser check itself can fail: a page with an image that does not decode, a console error, a fetch and a
// missing section is caught on each count.
TEST_F(Report, BrowserCheckCatchesBrokenPages) {
  const std::string chromium = find_chromium();
  if (chromium.empty()) GTEST_SKIP() << "chromium is not installed (scripts/setup installs it)";
  const std::string broken =
      "<!DOCTYPE html><html><head><title>broken</title></head><body><section id=\"coverage\"></section>"
      "<img alt=\"bad\" src=\"data:image/png;base64,AAAA\"><img alt=\"far\" src=\"missing.png\">"
      "<div style=\"width: 3000px\">wide</div><script>console.error('boom')</script></body></html>";
  const BrowserVerdict verdict = load_in_browser(chromium, broken, dir_);
  ASSERT_TRUE(verdict.ran) << verdict.failure;
  const std::string problems = verdict.problems.dump();
  for (const char* expected : {"image not decoded: bad", "image not decoded: far", "console.error: boom",
                               "missing section views", "external reference: missing.png", "wider than the window"})
    EXPECT_NE(problems.find(expected), std::string::npos) << expected << " in " << problems;
  EXPECT_FALSE(verdict.console_lines.empty());
}

}  // namespace
}  // namespace vdrig::pipeline
