#include "agv/report/svg.hpp"

#include <charconv>
#include <cmath>

#include "agv/report/text_file.hpp"

namespace agv::report {

std::string xmlEscape(std::string_view text) {
  std::string out;
  out.reserve(text.size());
  for (const char c : text) {
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
        if (static_cast<unsigned char>(c) < 0x20U && c != '\t' && c != '\n' && c != '\r') {
          out += "\xEF\xBF\xBD";  // U+FFFD: the character cannot appear in XML 1.0
        } else {
          out += c;
        }
    }
  }
  return out;
}

std::string svgNumber(double v) {
  if (!std::isfinite(v)) {
    return "0";  // a coordinate that cannot be drawn; keep the document valid
  }
  char buf[64];
  const std::to_chars_result r = std::to_chars(buf, buf + sizeof buf, v, std::chars_format::fixed, 2);
  if (r.ec != std::errc()) {
    return "0";
  }
  std::string s(buf, r.ptr);
  if (s == "-0.00") {
    s = "0.00";
  }
  return s;
}

void SvgPoints::add(double x, double y) {
  if (!text_.empty()) {
    text_ += ' ';
  }
  text_ += svgNumber(x);
  text_ += ',';
  text_ += svgNumber(y);
}

SvgDocument::SvgDocument(double width, double height, SvgAttrs rootAttrs) {
  body_ = "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"" + svgNumber(width) + "\" height=\"" + svgNumber(height) +
          "\"";
  for (const SvgAttr& a : rootAttrs) {
    body_ += ' ';
    body_ += a.name;
    body_ += "=\"";
    body_ += xmlEscape(a.value);
    body_ += '"';
  }
  body_ += ">\n";
  add("rect", {{"width", "100%"}, {"height", "100%"}, {"fill", "white"}});
}

void SvgDocument::startTag(const char* element, SvgAttrs attrs) {
  body_ += '<';
  body_ += element;
  for (const SvgAttr& a : attrs) {
    body_ += ' ';
    body_ += a.name;
    body_ += "=\"";
    body_ += xmlEscape(a.value);
    body_ += '"';
  }
}

void SvgDocument::endLineAtTopLevel() {
  if (open_.empty()) {
    body_ += '\n';
  }
}

void SvgDocument::add(const char* element, SvgAttrs attrs) {
  startTag(element, attrs);
  body_ += "/>";
  endLineAtTopLevel();
}

void SvgDocument::addText(const char* element, SvgAttrs attrs, std::string_view text) {
  startTag(element, attrs);
  body_ += '>';
  body_ += xmlEscape(text);
  body_ += "</";
  body_ += element;
  body_ += '>';
  endLineAtTopLevel();
}

void SvgDocument::open(const char* element, SvgAttrs attrs) {
  startTag(element, attrs);
  body_ += '>';
  open_.emplace_back(element);
}

void SvgDocument::text(std::string_view text) {
  body_ += xmlEscape(text);
}

void SvgDocument::close() {
  if (open_.empty()) {
    return;
  }
  body_ += "</" + open_.back() + ">";
  open_.pop_back();
  endLineAtTopLevel();
}

std::string SvgDocument::str() const {
  std::string s = body_;
  for (auto it = open_.rbegin(); it != open_.rend(); ++it) {
    s += "</" + *it + ">";
  }
  if (!open_.empty()) {
    s += '\n';
  }
  return s + "</svg>\n";
}

bool SvgDocument::save(const std::string& path, std::string& error) const {
  return writeTextFile(path, str(), error);
}

}  // namespace agv::report
