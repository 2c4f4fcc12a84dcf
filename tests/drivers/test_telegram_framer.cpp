// TelegramFramer: telegrams split at every read boundary, garbage, truncated, oversized and
// damaged telegrams, each counted.
#include <string>
#include <vector>

#include "agv/drivers/protocol/sick/telegram_framer.hpp"
#include "agv_test.hpp"
#include "sick_telegrams.hpp"

using agv::Span;
using agv::drivers::sick::Framing;
using agv::drivers::sick::TelegramFramer;

namespace {
std::vector<std::uint8_t> bytes(const std::string& s) {
  return std::vector<std::uint8_t>(s.begin(), s.end());
}

/// Feeds `stream` in chunks of `chunk` bytes and collects every telegram.
std::vector<std::string> run(TelegramFramer& f, const std::vector<std::uint8_t>& stream, std::size_t chunk) {
  std::vector<std::string> out;
  std::size_t pos = 0;
  while (pos < stream.size()) {
    const std::size_t n = std::min(chunk, stream.size() - pos);
    std::size_t fed = 0;
    while (fed < n) {
      fed += f.feed(Span<const std::uint8_t>(stream.data() + pos + fed, n - fed));
      Span<const std::uint8_t> t;
      while (f.next(t)) {
        out.emplace_back(t.begin(), t.end());
      }
    }
    pos += n;
  }
  return out;
}

void append(std::vector<std::uint8_t>& a, const std::vector<std::uint8_t>& b) {
  a.insert(a.end(), b.begin(), b.end());
}
}  // namespace

TEST_CASE("CoLa A telegrams are delivered whole for every read size, garbage counted", "[drivers][laser]") {
  std::vector<std::uint8_t> stream = bytes("noise");
  append(stream, agv::test::stxEtx("sSN one"));
  append(stream, bytes("\r\n"));
  append(stream, agv::test::stxEtx("sSN two 1 2 3"));
  append(stream, agv::test::stxEtx(""));
  for (std::size_t chunk : {std::size_t{1}, std::size_t{2}, std::size_t{3}, std::size_t{7}, std::size_t{64}}) {
    TelegramFramer f(Framing::ColaA);
    const auto t = run(f, stream, chunk);
    REQUIRE(t.size() == 3U);
    CHECK(t[0] == "sSN one");
    CHECK(t[1] == "sSN two 1 2 3");
    CHECK(t[2].empty());
    CHECK(f.counters().telegrams == 3U);
    CHECK(f.counters().garbageBytes == 7U);  // "noise" + CR LF
    CHECK(f.counters().truncated == 0U);
    CHECK(f.buffered() == 0U);
  }
}

TEST_CASE("CoLa A: a new STX before the ETX counts the cut telegram as truncated", "[drivers][laser]") {
  std::vector<std::uint8_t> stream = bytes("\x02sSN cut in the mid");
  append(stream, agv::test::stxEtx("sSN whole"));
  TelegramFramer f(Framing::ColaA);
  const auto t = run(f, stream, 5);
  REQUIRE(t.size() == 1U);
  CHECK(t[0] == "sSN whole");
  CHECK(f.counters().truncated == 1U);
}

TEST_CASE("CoLa A: an oversized telegram is skipped to its ETX and the next one survives", "[drivers][laser]") {
  std::vector<std::uint8_t> stream;
  stream.push_back(0x02);
  stream.insert(stream.end(), TelegramFramer::kCapacity + 100, 'A');
  stream.push_back(0x03);
  append(stream, agv::test::stxEtx("sSN after"));
  TelegramFramer f(Framing::ColaA);
  const auto t = run(f, stream, 4096);
  REQUIRE(t.size() == 1U);
  CHECK(t[0] == "sSN after");
  CHECK(f.counters().oversized == 1U);
  CHECK(f.counters().telegrams == 1U);
}

TEST_CASE("CoLa A: reset in the middle of a telegram counts it as truncated", "[drivers][laser]") {
  TelegramFramer f(Framing::ColaA);
  const auto part = bytes("\x02sSN half");
  CHECK(f.feed(Span<const std::uint8_t>(part.data(), part.size())) == part.size());
  Span<const std::uint8_t> t;
  CHECK_FALSE(f.next(t));
  f.reset();
  CHECK(f.counters().truncated == 1U);
  CHECK(f.buffered() == 0U);
  const auto whole = agv::test::stxEtx("sSN next");
  CHECK(run(f, whole, 3).size() == 1U);
}

TEST_CASE("CoLa B telegrams survive any split, garbage and a run of 0x02 before the marker", "[drivers][laser]") {
  const std::vector<std::uint8_t> p1 =
      bytes("sAN mNPOSGetData \x01\x02\x03\x02\x02\x02\x02");  // payload holding a marker
  const std::vector<std::uint8_t> p2(300, 0x55);
  std::vector<std::uint8_t> stream = bytes("xy\x02\x02");
  append(stream, agv::test::colaB(p1));
  append(stream, bytes("\x02\x02\x02\x02\x02"));  // 5 x STX then a real telegram: the first is noise
  append(stream, agv::test::colaB(p2));
  for (std::size_t chunk : {std::size_t{1}, std::size_t{3}, std::size_t{9}, std::size_t{1000}}) {
    TelegramFramer f(Framing::ColaB);
    const auto t = run(f, stream, chunk);
    REQUIRE(t.size() == 2U);
    CHECK(std::vector<std::uint8_t>(t[0].begin(), t[0].end()) == p1);
    CHECK(std::vector<std::uint8_t>(t[1].begin(), t[1].end()) == p2);
    CHECK(f.counters().garbageBytes == 9U);  // "xy\2\2" + the five 0x02 before the second marker
    CHECK(f.counters().oversized == 0U);
    CHECK(f.counters().checksumErrors == 0U);
  }
}

TEST_CASE("CoLa B: checksum errors, oversized lengths and truncation are counted", "[drivers][laser]") {
  const std::vector<std::uint8_t> good = bytes("sAN ok");
  std::vector<std::uint8_t> damaged = agv::test::colaB(bytes("sAN damaged"));
  damaged[10] ^= 0x40;
  agv::test::BeWriter big;
  big.u32(0x02020202);
  big.u32(static_cast<std::uint32_t>(TelegramFramer::kCapacity));  // more than fits
  std::vector<std::uint8_t> stream = damaged;
  append(stream, big.b);
  append(stream, agv::test::colaB(good));
  TelegramFramer f(Framing::ColaB);
  auto t = run(f, stream, 16);
  REQUIRE(t.size() == 1U);
  CHECK(t[0] == "sAN ok");
  CHECK(f.counters().checksumErrors == 1U);
  CHECK(f.counters().oversized == 1U);

  // Connection lost half way through a telegram.
  const auto half = agv::test::colaB(bytes("sAN interrupted"));
  CHECK(f.feed(Span<const std::uint8_t>(half.data(), 12)) == 12U);
  Span<const std::uint8_t> tel;
  CHECK_FALSE(f.next(tel));
  f.reset();
  CHECK(f.counters().truncated == 1U);
  t = run(f, agv::test::colaB(good), 2);
  CHECK(t.size() == 1U);
}

TEST_CASE("Framer: a full buffer is never stuck and steady-state use does not allocate", "[drivers][laser]") {
  static TelegramFramer f(Framing::ColaA);
  std::vector<std::uint8_t> noise(3 * TelegramFramer::kCapacity, 'n');
  noise[0] = 0x02;  // an endless telegram
  const auto tel = agv::test::stxEtx("sSN x");
  std::size_t delivered = 0;
  AGV_CHECK_NO_ALLOCATIONS({
    std::size_t pos = 0;
    for (int guard = 0; guard < 1000 && pos < noise.size(); ++guard) {
      pos += f.feed(Span<const std::uint8_t>(noise.data() + pos, noise.size() - pos));
      Span<const std::uint8_t> t;
      while (f.next(t)) {
        ++delivered;
      }
    }
    CHECK(pos == noise.size());
    CHECK(f.feed(Span<const std::uint8_t>(tel.data(), tel.size())) == tel.size());
    Span<const std::uint8_t> t;
    while (f.next(t)) {
      ++delivered;
    }
  });
  CHECK(delivered == 1U);  // the telegram after the endless one is found at its STX
  CHECK(f.counters().oversized == 1U);
}
