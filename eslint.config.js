// ESLint for the browser code (web/*.js, plain ES modules run as-is by the browser): the recommended rules.
// `npx eslint web` (scripts/test.sh). The vendored uPlot is not ours to lint.
import js from "@eslint/js";
import globals from "globals";

export default [
  { ignores: ["web/vendor/**"] },
  {
    files: ["web/**/*.js"],
    ...js.configs.recommended,
    languageOptions: {
      ecmaVersion: 2022,
      sourceType: "module",
      globals: globals.browser,
    },
  },
];
