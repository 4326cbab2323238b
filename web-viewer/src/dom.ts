// The page's elements by id (index.html).
export const $ = <T extends HTMLElement = HTMLElement>(id: string) => document.getElementById(id) as T;
