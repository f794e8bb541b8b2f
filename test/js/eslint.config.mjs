// eslint for the page (web/) and the Node test clients: `bash tools/lint` runs it with this file.
import js from "@eslint/js";
import globals from "globals";

export default [
  js.configs.recommended,
  {
    files: ["**/*.js", "**/*.mjs"],
    languageOptions: {
      ecmaVersion: 2022,
      sourceType: "module",
      globals: { ...globals.browser, ROSLIB: "readonly", uPlot: "readonly" },
    },
    rules: {
      "no-unused-vars": ["error", { args: "none", caughtErrors: "none" }],
    },
  },
  {
    files: ["test/js/**/*.mjs"],
    languageOptions: { globals: { ...globals.node } },
  },
  { ignores: ["web/vendor/**", "web/node_modules/**", "test/js/node_modules/**"] },
];
