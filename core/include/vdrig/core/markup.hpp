// Escaping text for the two markups vdrig generates: HTML and SVG (the session report, pipeline/src/html.hpp; plots,
// viewer/plot.hpp) and Markdown tables (docs/results.md, bench/results_table.cpp). One definition each, so that every
// writer of a markup escapes the same characters.
#pragma once

#include <string>

namespace vdrig::core {

/// `text` safe inside HTML element content and double-quoted attribute values: & < > " become entities.
std::string escape_html(const std::string& text);

/// `text` safe inside a cell of a Markdown (GitHub) table: every '|' becomes "\|", which would otherwise end the
/// cell. Nothing else is changed (the cells hold figures and short notes, not HTML).
std::string escape_markdown_table_cell(const std::string& text);

}  // namespace vdrig::core
