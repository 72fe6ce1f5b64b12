// Preloaded into windowed tandem-view runs of the sanitizer suite only:
// SDL and libglvnd unload D-Bus and the Mesa driver before exit, and
// LeakSanitizer then reports what they kept as "<unknown module>", which no
// suppression can name. With dlclose a no-op every library stays mapped, so
// tests/lsan_system_libraries.supp can suppress them by name and any other
// report is Tandem's own.
extern "C" int dlclose(void*) {
  return 0;
}
