// The web console's guard (docs/web.md, "Threat model"): a request without the token is 401; a state-changing one
// needs the token in its header and this server's Origin (403 otherwise, also for a foreign Host); files are reached
// by session name only (traversal in any spelling is 404); a body above the limit is 413; a flooding client gets 429
// while another client is still served.
#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <vector>

#include "web_support.hpp"

namespace vdrig::web::testing {
namespace {
using nlohmann::json;

std::string with_token(const Console& c) { return "X-Vdrig-Token: " + c.token() + "\r\n"; }

TEST(WebSecurity, EveryRequestWithoutTheTokenIs401) {
  vdrig::test::TempDir root("web_token");
  Console c(root.path());
  ASSERT_TRUE(c.started()) << c.started().describe();
  for (const std::string path : {"/", "/static/app.js", "/api/status", "/api/sessions", "/api/events",
                                 "/files/s1/manifest.json", "/no/such/page"}) {
    EXPECT_EQ(http(c.port(), request("GET", path, c.host())).status, 401) << path;
    EXPECT_EQ(http(c.port(), request("GET", path, c.host(), "X-Vdrig-Token: " + std::string(48, '0') + "\r\n")).status,
              401)
        << path << " with a wrong token";
  }
  EXPECT_EQ(http(c.port(), request("GET", "/?token=" + c.token().substr(1), c.host())).status, 401) << "a prefix";
  EXPECT_EQ(http(c.port(), request("POST", "/api/pause", c.host(), "Origin: " + c.origin() + "\r\n", "{}")).status,
            401);

  // The first load with the token in the query: a cookie, and the page again without the token in its address.
  const HttpReply first = http(c.port(), request("GET", "/?token=" + c.token(), c.host()));
  ASSERT_EQ(first.status, 303);
  EXPECT_EQ(first.header("Location"), "/");
  const std::string cookie = first.header("Set-Cookie");
  EXPECT_NE(cookie.find("HttpOnly"), std::string::npos) << cookie;
  EXPECT_NE(cookie.find("SameSite=Strict"), std::string::npos) << cookie;
  const std::string pair = cookie.substr(0, cookie.find(';'));
  const HttpReply page = http(c.port(), request("GET", "/", c.host(), "Cookie: " + pair + "\r\n"));
  ASSERT_EQ(page.status, 200);
  EXPECT_NE(page.body.find("<title>vdrig console</title>"), std::string::npos);
  EXPECT_NE(page.header("Content-Security-Policy").find("script-src 'self'"), std::string::npos);
  const HttpReply status = http(c.port(), request("GET", "/api/status", c.host(), with_token(c)));
  ASSERT_EQ(status.status, 200) << status.body;
  EXPECT_EQ(json::parse(status.body).value("state", ""), "idle");
}

TEST(WebSecurity, APostNeedsTheTokenHeaderAndThisServersOrigin) {
  vdrig::test::TempDir root("web_origin");
  Console c(root.path());
  ASSERT_TRUE(c.started()) << c.started().describe();
  const std::string token = with_token(c);
  auto post = [&](const std::string& headers, const std::string& host) {
    return http(c.port(), request("POST", "/api/abort", host, headers, "{}"));
  };
  EXPECT_EQ(post(token + "Origin: http://evil.example\r\n", c.host()).status, 403);
  EXPECT_EQ(post(token + "Origin: http://127.0.0.1:1\r\n", c.host()).status, 403) << "another port is another origin";
  EXPECT_EQ(post(token + "Origin: null\r\n", c.host()).status, 403);
  EXPECT_EQ(post(token, c.host()).status, 403) << "no Origin";
  // The cookie alone (what a cross-site form would carry) is not enough for a POST.
  EXPECT_EQ(
      post("Cookie: vdrig_token_" + std::to_string(c.port()) + "=" + c.token() + "\r\nOrigin: " + c.origin() + "\r\n",
           c.host())
          .status,
      403);
  // DNS rebinding: a foreign name pointed at this machine is refused whatever it sends.
  EXPECT_EQ(post(token + "Origin: http://evil.example:" + std::to_string(c.port()) + "\r\n",
                 "evil.example:" + std::to_string(c.port()))
                .status,
            403);
  EXPECT_EQ(http(c.port(), request("GET", "/api/status", "evil.example", token)).status, 403);
  // The right token and Origin reach the daemon, whose answer is relayed: nothing to abort.
  const HttpReply ok = post(token + "Origin: " + c.origin() + "\r\n", c.host());
  EXPECT_EQ(ok.status, 409) << ok.body;
  EXPECT_EQ(json::parse(ok.body).value("code", ""), "invalid_state") << ok.body;
  const HttpReply localhost = post(token + "Origin: http://localhost:" + std::to_string(c.port()) + "\r\n",
                                   "localhost:" + std::to_string(c.port()));
  EXPECT_EQ(localhost.status, 409) << localhost.body;
  // GET never changes state: a command by GET is no route.
  EXPECT_EQ(http(c.port(), request("GET", "/api/abort", c.host(), token)).status, 404);
}

TEST(WebSecurity, FilesAreServedBySessionNameOnly) {
  vdrig::test::TempDir root("web_files");
  Console c(root.path());
  ASSERT_TRUE(c.started()) << c.started().describe();
  const std::string token = with_token(c);
  // A session to serve: started through the console, a short one.
  const HttpReply started =
      http(c.port(), request("POST", "/api/start", c.host(), token + "Origin: " + c.origin() + "\r\n",
                             R"({"session":"s1","scheme":"spiral:4:1@80","bracket":"fixed:0.01"})"));
  ASSERT_EQ(started.status, 200) << started.body;
  const HttpReply manifest = http(c.port(), request("GET", "/files/s1/manifest.json", c.host(), token));
  ASSERT_EQ(manifest.status, 200) << manifest.body;
  EXPECT_EQ(json::parse(manifest.body).value("scheme", ""), "spiral:4:1@80");
  // A secret beside the sessions folder, and one inside a session, that no request may reach.
  capture::testing::write_text(root.path() / "secret.txt", "secret\n");
  capture::testing::write_text(root.path() / "sessions" / "s1" / "notes.txt", "secret\n");
  fs::create_directory_symlink(root.path() / "sessions" / "s1", root.path() / "sessions" / "linked");
  fs::create_symlink(root.path() / "secret.txt", root.path() / "sessions" / "s1" / "journal.jsonl.link");
  for (const std::string path : {"/files/../secret.txt",
                                 "/files/s1/../../secret.txt",
                                 "/files/s1/..%2f..%2fsecret.txt",
                                 "/files/%2e%2e/secret.txt",
                                 "/files/..%2fsecret.txt/manifest.json",
                                 "/files/%2e%2e%2f%2e%2e/secret.txt",
                                 "/files/s1/%2e%2e%2f%2e%2e%2fsecret.txt",
                                 "/files//etc/passwd",
                                 "/files/%2fetc/passwd",
                                 "/files/s1/%2fetc%2fpasswd",
                                 "/%2e%2e/%2e%2e/etc/passwd",
                                 "/../../etc/passwd",
                                 "/etc/passwd",
                                 "/files/s1/notes.txt",
                                 "/files/s1/journal.jsonl.link",
                                 "/files/s1/frames%2fview_0000_e00.png",
                                 "/files/nosuch/manifest.json",
                                 "/files/.hidden/manifest.json",
                                 "/files/s1%00/manifest.json",
                                 "/files/linked/manifest.json",
                                 "/static/../secret.txt",
                                 "/static/%2e%2e/%2e%2e/secret.txt"}) {
    const HttpReply r = http(c.port(), request("GET", path, c.host(), token));
    EXPECT_EQ(r.status, 404) << path << ": " << r.body;
    EXPECT_EQ(r.body.find("secret"), std::string::npos) << path;
  }
}

TEST(WebSecurity, FramesAndTheStageTakeOnlyNamesAndNumbers) {
  vdrig::test::TempDir root("web_frames");
  Console c(root.path());
  ASSERT_TRUE(c.started()) << c.started().describe();
  const std::string token = with_token(c);
  const std::string post_headers = token + "Origin: " + c.origin() + "\r\n";
  ASSERT_EQ(http(c.port(), request("POST", "/api/start", c.host(), post_headers,
                                   R"({"session":"s1","scheme":"spiral:4:1@80","bracket":"fixed:0.01"})"))
                .status,
            200);
  // The first frame, once the journal has it: the thumbnail of a 160x120 frame, as a PNG.
  HttpReply frame;
  for (int i = 0; i < 100 && frame.status != 200; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
    frame = http(c.port(), request("GET", "/api/frame?session=s1&view=0&bracket=0", c.host(), token));
  }
  ASSERT_EQ(frame.status, 200) << frame.body;
  const json f = json::parse(frame.body);
  EXPECT_EQ(f.value("width", 0), 160);
  EXPECT_EQ(f.value("thumb_width", 0), 160);
  EXPECT_EQ(f.value("png_base64", "").rfind("iVBORw0KGgo", 0), 0u) << "a PNG's signature in base64";
  fs::create_directory_symlink(root.path() / "sessions" / "s1", root.path() / "sessions" / "linked");
  for (const std::string query :
       {"session=..&view=0&bracket=0", "session=..%2fsessions%2fs1&view=0&bracket=0", "session=linked&view=0&bracket=0",
        "session=nosuch&view=0&bracket=0", "session=s1&view=9999&bracket=0", "session=%2fetc&view=0&bracket=0"}) {
    const HttpReply r = http(c.port(), request("GET", "/api/frame?" + query, c.host(), token));
    EXPECT_EQ(r.status, 404) << query << ": " << r.body;
  }
  for (const std::string query : {"session=s1&view=-1&bracket=0", "session=s1&view=0x1&bracket=0", "session=s1&view=0",
                                  "session=s1&view=1234567&bracket=0"}) {
    const HttpReply r = http(c.port(), request("GET", "/api/frame?" + query, c.host(), token));
    EXPECT_EQ(r.status, 400) << query << ": " << r.body;
  }
  // The journal's tail: its last lines only. The frame's file is written before its journal line, so wait until the
  // whole journal has more lines than the tail asks for (the capture goes on meanwhile: ask for the tail after).
  HttpReply whole;
  for (int i = 0; i < 200 && std::count(whole.body.begin(), whole.body.end(), '\n') < 3; ++i) {
    if (i > 0) std::this_thread::sleep_for(std::chrono::milliseconds(50));
    whole = http(c.port(), request("GET", "/files/s1/journal.jsonl", c.host(), token));
  }
  ASSERT_GE(std::count(whole.body.begin(), whole.body.end(), '\n'), 3) << whole.body;
  const HttpReply tail = http(c.port(), request("GET", "/files/s1/journal.jsonl?tail=2", c.host(), token));
  ASSERT_EQ(tail.status, 200);
  EXPECT_EQ(std::count(tail.body.begin(), tail.body.end(), '\n'), 2) << tail.body;
  // move takes exactly two finite numbers; anything else is refused before the daemon sees it.
  for (const std::string body :
       {R"({"pan_deg":"10","tilt_deg":0})", R"({"pan_deg":10})", R"({"pan_deg":10,"tilt_deg":0,"rig":{}})", R"([10,0])",
        R"({"pan_deg":1e999,"tilt_deg":0})"}) {
    const HttpReply r = http(c.port(), request("POST", "/api/move", c.host(), post_headers, body));
    EXPECT_EQ(r.status, 400) << body << ": " << r.body;
  }
  // A move without the token header is refused like every state-changing request.
  EXPECT_EQ(http(c.port(), request("POST", "/api/move", c.host(), token, R"({"pan_deg":1,"tilt_deg":0})")).status, 403);
}

TEST(WebSecurity, ABodyAboveTheLimitIs413) {
  vdrig::test::TempDir root("web_body");
  ServerOptions options;
  options.max_body_bytes = 4096;
  Console c(root.path(), options);
  ASSERT_TRUE(c.started()) << c.started().describe();
  const std::string headers = with_token(c) + "Origin: " + c.origin() + "\r\n";
  const std::string big = R"({"session":")" + std::string(5000, 'a') + R"("})";
  EXPECT_EQ(http(c.port(), request("POST", "/api/start", c.host(), headers, big)).status, 413);
  // Just below the limit the request is read and the daemon's own validation answers (the name is too long).
  const std::string fits = R"({"session":")" + std::string(4000, 'a') + R"("})";
  const HttpReply r = http(c.port(), request("POST", "/api/start", c.host(), headers, fits));
  EXPECT_EQ(r.status, 400) << r.body;
  EXPECT_EQ(json::parse(r.body).value("code", ""), "invalid_argument") << r.body;
}

TEST(WebSecurity, AFloodingClientGets429WhileAnotherIsServed) {
  vdrig::test::TempDir root("web_flood");
  ServerOptions options;
  options.rate_per_s = 10;
  options.rate_burst = 20;
  Console c(root.path(), options);
  ASSERT_TRUE(c.started()) << c.started().describe();
  const std::string get = request("GET", "/static/style.css", c.host(), with_token(c));
  std::atomic<int> ok{0}, limited{0}, other{0};
  std::atomic<bool> polite_done{false};
  const auto start = std::chrono::steady_clock::now();
  std::thread flood([&] {
    for (int i = 0; i < 5000 && (i < 200 || !polite_done); ++i) {  // through the other client's requests
      const int status = http(c.port(), get).status;
      (status == 200 ? ok : status == 429 ? limited : other) += 1;
    }
  });
  // Another client (another address, as the server sees it), at a polite pace while the flood lasts.
  std::vector<int> polite;
  for (int i = 0; i < 5; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
    polite.push_back(http(c.port(), get, "127.0.0.2").status);
  }
  polite_done = true;
  flood.join();
  const double elapsed_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  for (const int s : polite) EXPECT_EQ(s, 200);
  EXPECT_EQ(other, 0);
  EXPECT_GE(ok, 20) << "the burst";
  // At most the burst and what the rate refilled meanwhile got through; the flood sent far more.
  EXPECT_LE(ok, 20 + 10 * elapsed_s + 2) << "in " << elapsed_s << " s";
  EXPECT_GT(limited, ok) << "ok " << ok << ", 429 " << limited << " in " << elapsed_s << " s";
  const HttpReply refused = http(c.port(), get);
  if (refused.status == 429) {
    EXPECT_EQ(refused.header("Retry-After"), "1");
  }
}

}  // namespace
}  // namespace vdrig::web::testing
