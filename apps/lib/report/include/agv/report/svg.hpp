#pragma once
/// @file svg.hpp
/// The one SVG writer of the programs' plots: elements with attributes, text content and nested
/// elements (a <text> of coloured <tspan>s), every attribute value and every text XML-escaped.

#include <initializer_list>
#include <string>
#include <string_view>
#include <vector>

namespace agv::report {

/// `text` as XML character data or attribute value: & < > " ' become entities; control characters
/// XML 1.0 does not allow (all below 0x20 except tab, LF and CR) become U+FFFD.
std::string xmlEscape(std::string_view text);

/// A coordinate or length as written into a plot: fixed point with 2 decimals, locale-free
/// ("-0.00" is written "0.00").
std::string svgNumber(double v);

/// One attribute of an element; text values are escaped when written, numbers use `svgNumber`.
struct SvgAttr {
  SvgAttr(const char* attrName, std::string_view text) : name(attrName), value(text) {}
  SvgAttr(const char* attrName, const char* text) : name(attrName), value(text) {}
  SvgAttr(const char* attrName, const std::string& text) : name(attrName), value(text) {}
  SvgAttr(const char* attrName, double number) : name(attrName), value(svgNumber(number)) {}
  SvgAttr(const char* attrName, int number) : name(attrName), value(std::to_string(number)) {}

  const char* name;
  std::string value;
};
using SvgAttrs = std::initializer_list<SvgAttr>;

/// The `points` of a polyline: "x,y x,y ...".
class SvgPoints {
 public:
  void add(double x, double y);
  const std::string& str() const noexcept { return text_; }
  bool empty() const noexcept { return text_.empty(); }

 private:
  std::string text_;
};

/// An SVG document of `width` x `height` pixels on a white background. Elements are appended in
/// drawing order; `str()` closes whatever is still open.
class SvgDocument {
 public:
  /// `rootAttrs` go on the <svg> element after xmlns, width and height (e.g. font-family).
  SvgDocument(double width, double height, SvgAttrs rootAttrs = {});

  /// <element attrs/>
  void add(const char* element, SvgAttrs attrs);
  /// <element attrs>text</element>
  void addText(const char* element, SvgAttrs attrs, std::string_view text);
  /// <element attrs> ... until the matching `close()`.
  void open(const char* element, SvgAttrs attrs);
  /// Character data inside the innermost open element.
  void text(std::string_view text);
  /// </element> of the innermost open element (none: no effect).
  void close();

  /// The document, every open element closed.
  std::string str() const;
  /// Writes `str()` to `path`; false with `error` ("cannot write PATH: reason").
  bool save(const std::string& path, std::string& error) const;

 private:
  void startTag(const char* element, SvgAttrs attrs);
  void endLineAtTopLevel();

  std::string body_;
  std::vector<std::string> open_;
};

}  // namespace agv::report
