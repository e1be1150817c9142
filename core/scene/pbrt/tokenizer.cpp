#include "core/scene/pbrt/tokenizer.h"

#include <utility>

namespace render::pbrt {

Tokenizer::Tokenizer(std::string text, std::string file)
    : text_(std::move(text)), file_(std::move(file)) {}

std::optional<Token> Tokenizer::next() {
    if (peeked_) {
        peeked_ = false;
        return std::move(peek_);
    }
    return scan();
}

const std::optional<Token>& Tokenizer::peek() {
    if (!peeked_) {
        peek_ = scan();
        peeked_ = true;
    }
    return peek_;
}

std::optional<Token> Tokenizer::scan() {
    auto is_space = [](char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\n'; };
    while (pos_ < text_.size()) {
        const char c = text_[pos_];
        if (c == '\n') {
            ++line_;
            ++pos_;
        } else if (is_space(c)) {
            ++pos_;
        } else if (c == '#') {
            while (pos_ < text_.size() && text_[pos_] != '\n') ++pos_;
        } else {
            break;
        }
    }
    if (pos_ >= text_.size()) return std::nullopt;
    Token token;
    token.where = SourceLocation{file_, line_};
    const char c = text_[pos_];
    if (c == '[' || c == ']') {
        token.text = std::string(1, c);
        ++pos_;
        return token;
    }
    if (c == '"') {
        token.quoted = true;
        ++pos_;
        while (true) {
            if (pos_ >= text_.size()) throw SceneError(token.where, "unterminated string");
            const char s = text_[pos_++];
            if (s == '"') break;
            if (s == '\n') throw SceneError(token.where, "a newline inside a string");
            if (s != '\\') {
                token.text += s;
                continue;
            }
            if (pos_ >= text_.size()) throw SceneError(token.where, "unterminated string");
            const char e = text_[pos_++];
            switch (e) {
                case 'n':
                    token.text += '\n';
                    break;
                case 't':
                    token.text += '\t';
                    break;
                case 'b':
                    token.text += '\b';
                    break;
                case 'f':
                    token.text += '\f';
                    break;
                case 'r':
                    token.text += '\r';
                    break;
                case '\\':
                    token.text += '\\';
                    break;
                case '"':
                    token.text += '"';
                    break;
                case '\'':
                    token.text += '\'';
                    break;
                default:
                    throw SceneError(token.where,
                                     std::string("unknown escape \\") + e + " in a string");
            }
        }
        return token;
    }
    while (pos_ < text_.size()) {
        const char w = text_[pos_];
        if (is_space(w) || w == '"' || w == '[' || w == ']' || w == '#') break;
        token.text += w;
        ++pos_;
    }
    return token;
}

}  // namespace render::pbrt
