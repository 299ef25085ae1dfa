// What tools/code_limits.py must find, and what must not confuse it. Not compiled.
#include <cstdint>

namespace sample {

constexpr std::int64_t kMany = 1'000'000'000;  // digit separators are no char literals

int seven(int a, int b, int c, int d, int e, int f, int g) {
  return a + b + c + d + e + f + g;
}

struct Holder {
  int six(int a, int b, int c, int d, int e, int f) const { return a + b + c + d + e + f; }
  Holder(int a, int b) : a_(a), b_{b} {}
  int a_, b_;
};

struct Braced {
  Braced(int a, int b)
      : a_{a},
        b_({b}) {
    a_ += b_;
  }
  int a_, b_;
};

class Labelled {
 public:
  // A comment between the label and the signature.
  int three(int a) const {
    return a;
  }
};

struct Same {
  bool operator==(const Same& o) const {
    if (o.v == v) { return true; }
    return false;
  }
  int v;
};

const char* braces() {
  const char* open = "{{{";  // braces in strings
  const char close = '}';    // and in char literals
  return close == '}' ? open : "}";
}

/* a comment with a { that is never closed
*/
int long_one() {
  // A function's length counts its lines from the signature to the closing brace, blank or not;
  // the braces of its loops and lambdas are its own.
  int x = 0;
  for (int i = 0; i < 10; ++i) {
    x += [&] { return i; }();
  }




















































  return x;
}

}  // namespace sample
