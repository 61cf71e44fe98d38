// Escaping for the markups vdrig writes (core/markup.hpp): the report's HTML and the plots' SVG and docs/results.md's
// tables.
#include <gtest/gtest.h>

#include "vdrig/core/markup.hpp"

namespace vdrig::core {
namespace {

TEST(Markup, HtmlEscapesTheFourSpecialCharacters) {
  EXPECT_EQ(escape_html("a < b && c > \"d\""), "a &lt; b &amp;&amp; c &gt; &quot;d&quot;");
  EXPECT_EQ(escape_html("plain text, 'single' | pipe"), "plain text, 'single' | pipe");
  EXPECT_EQ(escape_html(""), "");
}

TEST(Markup, MarkdownTableCellEscapesOnlyPipes) {
  EXPECT_EQ(escape_markdown_table_cell("m | n"), "m \\| n");
  EXPECT_EQ(escape_markdown_table_cell("|x|"), "\\|x\\|");
  EXPECT_EQ(escape_markdown_table_cell("<b> & 3.5 %"), "<b> & 3.5 %");
}

}  // namespace
}  // namespace vdrig::core
