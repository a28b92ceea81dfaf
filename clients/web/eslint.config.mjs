// ESLint's rules for the web app (flat config): eslint's recommended set,
// functions of at most 60 lines, and the modules' layering: src/lib holds
// pure helpers (no DOM, no three.js, importing only each other), and no
// page (player, live, library) imports another.

import js from '@eslint/js';
import globals from 'globals';

const PAGES = ['player', 'live', 'library'];

// Imports a module of page `page` (its entry `page.js` or its folder
// `page/`), from src/ (`./`) or from a folder beside it (`../`).
function pageImports(page) {
  return [`./${page}.js`, `./${page}/*`, `../${page}.js`, `../${page}/*`];
}

// No page imports another: each page's entry and folder may import its
// own modules and the shared ones, never another page's.
const pageLayers = PAGES.map((page) => ({
  files: [`src/${page}.js`, `src/${page}/**/*.js`],
  rules: {
    'no-restricted-imports': [
      'error',
      {
        patterns: [
          {
            group: PAGES.filter((other) => other !== page).flatMap(pageImports),
            message: 'A page imports no other page: move what both need to a shared module (src/*.js or src/lib).',
          },
        ],
      },
    ],
  },
}));

export default [
  { ignores: ['node_modules/', 'dist/'] },
  js.configs.recommended,
  {
    languageOptions: { ecmaVersion: 2022, sourceType: 'module' },
    linterOptions: { reportUnusedDisableDirectives: 'error' },
    rules: {
      'max-lines-per-function': ['error', { max: 60 }],
      'no-unused-vars': ['error', { args: 'after-used', argsIgnorePattern: '^_', caughtErrors: 'all' }],
      'prefer-const': 'error',
      'no-var': 'error',
      eqeqeq: ['error', 'always'],
      'object-shorthand': ['error', 'always'],
      'no-shadow': 'error',
      'no-param-reassign': 'off',
    },
  },
  { files: ['src/**/*.js'], ignores: ['src/lib/**'], languageOptions: { globals: globals.browser } },
  // The shared modules import no page.
  {
    files: ['src/*.js'],
    ignores: ['src/main.js', ...PAGES.map((page) => `src/${page}.js`)],
    rules: {
      'no-restricted-imports': [
        'error',
        {
          patterns: [{ group: PAGES.flatMap(pageImports), message: 'A shared module imports no page.' }],
        },
      ],
    },
  },
  ...pageLayers,
  // Pure helpers: the language's own globals only, and no DOM or three.js.
  {
    files: ['src/lib/**/*.js'],
    rules: {
      'no-restricted-imports': [
        'error',
        {
          patterns: [
            { group: ['three', 'three/*'], message: 'src/lib is pure: no three.js.' },
            { group: ['../*'], message: 'src/lib is pure: it imports only its own modules.' },
          ],
        },
      ],
    },
  },
  { files: ['*.mjs', 'test/**/*.mjs', 'testing/**/*.mjs'], languageOptions: { globals: globals.node } },
];
