/* Preloaded into every process of the sanitized test run (tests/sanitizers.env, built by
 * scripts/test-sanitized.sh; C, no sanitizer). dlclose() does nothing, so no shared object is
 * unloaded before LeakSanitizer runs at exit.
 *
 * Why: the Vulkan loader dlclose()s the validation layer and every driver at vkDestroyInstance.
 * A leak allocated by an unloaded module is printed from "<unknown module>" (or from a wrong
 * module whose mapping now covers the address), which no leak: suppression can match, and
 * memory held by its globals turns into leaks. With every module kept, each leak names the
 * library that allocated it, and tests/lsan.supp can suppress dependencies' leaks by name
 * while a leak in terravt's code still fails its test. */
int dlclose(void *handle) {
  (void)handle;
  return 0;
}
