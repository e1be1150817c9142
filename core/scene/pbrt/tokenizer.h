#pragma once

// Splits a pbrt-v4 scene file into tokens: bare words and numbers, "quoted strings" (with
// pbrt's escapes \n \t \b \f \r \\ \" \'), the brackets [ and ], and nothing for # comments.
// Every token knows its file and line. Reference: docs/reference/scene-format.md, "pbrt-v4 scenes".

#include <optional>
#include <string>

#include "core/base/error.h"

namespace render::pbrt {

struct Token {
    std::string text;  // the unquoted, unescaped text of a string
    bool quoted = false;
    SourceLocation where;

    bool is(const char* s) const { return !quoted && text == s; }
};

class Tokenizer {
  public:
    // `file` is the name used in messages.
    Tokenizer(std::string text, std::string file);

    // The next token; nothing at the end of the text. Throws SceneError (file:line) for an
    // unterminated string, a newline inside a string or an unknown escape.
    std::optional<Token> next();
    // The next token without consuming it.
    const std::optional<Token>& peek();

    const std::string& file() const { return file_; }

  private:
    std::optional<Token> scan();

    std::string text_;
    std::string file_;
    size_t pos_ = 0;
    int line_ = 1;
    bool peeked_ = false;
    std::optional<Token> peek_;
};

}  // namespace render::pbrt
