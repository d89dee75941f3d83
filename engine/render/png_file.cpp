// libpng behind two functions (see png_file.hpp).
#include "engine/render/png_file.hpp"

#include <png.h>

#include <cstdio>
#include <memory>
#include <stdexcept>
#include <string>
#include <system_error>
#include <vector>

namespace nexdyn {

namespace {

struct FileCloser {
  void operator()(std::FILE* f) const { std::fclose(f); }
};
using File = std::unique_ptr<std::FILE, FileCloser>;

// libpng reports errors by longjmp; this turns them into a message the caller throws after the
// libpng structures are gone.
void on_png_error(png_structp png, png_const_charp message) {
  auto* text = static_cast<std::string*>(png_get_error_ptr(png));
  *text = message;
  png_longjmp(png, 1);
}
void on_png_warning(png_structp, png_const_charp) {}

// Writes through libpng into an open file; returns "" or libpng's message. No C++ object with a
// destructor lives in this frame across the setjmp.
std::string write_rows(std::FILE* file, const Image& image, png_bytep* rows) {
  std::string error;
  png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, &error, on_png_error, on_png_warning);
  png_infop info = png ? png_create_info_struct(png) : nullptr;
  if (png == nullptr || info == nullptr) {
    png_destroy_write_struct(&png, nullptr);
    return "libpng could not start";
  }
  if (setjmp(png_jmpbuf(png))) {
    png_destroy_write_struct(&png, &info);
    return error.empty() ? "libpng failed" : error;
  }
  png_init_io(png, file);
  png_set_IHDR(png, info, static_cast<png_uint_32>(image.width), static_cast<png_uint_32>(image.height), 8,
               PNG_COLOR_TYPE_RGB, PNG_INTERLACE_NONE, PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
  png_write_info(png, info);
  png_write_image(png, rows);
  png_write_end(png, nullptr);
  png_destroy_write_struct(&png, &info);
  return "";
}

}  // namespace

void write_png(const std::filesystem::path& path, const Image& image) {
  if (image.width <= 0 || image.height <= 0 || image.rgb.size() != 3 * size_t(image.width) * size_t(image.height))
    throw std::runtime_error(path.string() + ": no picture to write");
  const std::filesystem::path tmp = path.string() + ".tmp";
  std::vector<png_bytep> rows(static_cast<size_t>(image.height));
  for (int j = 0; j < image.height; ++j)
    rows[static_cast<size_t>(j)] = const_cast<png_bytep>(&image.rgb[3 * size_t(j) * size_t(image.width)]);
  std::string error;
  {
    File file(std::fopen(tmp.string().c_str(), "wb"));
    if (!file) throw std::runtime_error(tmp.string() + ": cannot open for writing");
    error = write_rows(file.get(), image, rows.data());
    if (error.empty() && (std::fflush(file.get()) != 0 || std::ferror(file.get()) != 0))
      error = "write failed (disk full?)";
  }
  std::error_code ec;
  if (!error.empty()) {
    std::filesystem::remove(tmp, ec);
    throw std::runtime_error(path.string() + ": " + error);
  }
  std::filesystem::rename(tmp, path, ec);
  if (ec) throw std::runtime_error(path.string() + ": cannot rename into place: " + ec.message());
}

Image read_png(const std::filesystem::path& path) {
  png_image png{};
  png.version = PNG_IMAGE_VERSION;
  if (!png_image_begin_read_from_file(&png, path.string().c_str()))
    throw std::runtime_error(path.string() + ": not a readable PNG (" + png.message + ")");
  png.format = PNG_FORMAT_RGB;
  Image image;
  image.width = static_cast<int>(png.width);
  image.height = static_cast<int>(png.height);
  image.rgb.resize(PNG_IMAGE_SIZE(png));
  if (!png_image_finish_read(&png, nullptr, image.rgb.data(), 0, nullptr)) {
    const std::string message = png.message;
    png_image_free(&png);
    throw std::runtime_error(path.string() + ": " + message);
  }
  return image;
}

}  // namespace nexdyn
