// token.js: the form that asks for a token when the server's reads are closed (ipsd
// --read-token): shown above the view when an API read answers 401 (api.js onAuthNeeded), it
// keeps the token for this tab (sessionStorage) or, ticked, in this browser (localStorage), and
// then calls done() so the page reads again; the event stream reconnects by itself (setToken).
// A token the server refuses brings the form back with the server's message.
import { getToken, onAuthNeeded, setToken } from './api.js';
import { h } from './dom.js';

// Starts listening for 401s; the form goes before the element `before`. done(): the token was
// entered (the caller re-renders its view).
export function setupTokenPrompt(before, done) {
    let form = null;
    onAuthNeeded((err) => {
        const why = getToken()
            ? `This token was refused: ${err.message}`
            : 'This ipsd needs a token to read (it runs with --read-token). Enter a read or ' +
              'write token from the lab\'s token file.';
        if (form) {
            form.querySelector('.token-why').textContent = why;
            return;
        }
        const input = h('input', { id: 'token-prompt-input', type: 'password', required: true,
            autocomplete: 'off', size: 24, 'aria-describedby': 'token-prompt-why' });
        const remember = h('input', { id: 'token-prompt-remember', type: 'checkbox' });
        form = h('form', { class: 'token-prompt', 'data-testid': 'token-prompt',
            'aria-label': 'Token needed' },
        h('p', { id: 'token-prompt-why', class: 'token-why' }, why),
        h('label', { for: 'token-prompt-input' }, 'Token'), input,
        h('label', { class: 'small' }, remember, ' remember in this browser'),
        h('button', { type: 'submit' }, 'Use token'));
        form.addEventListener('submit', (e) => {
            e.preventDefault();
            const token = input.value.trim();
            if (!token) return;
            setToken(token, remember.checked);
            form.remove();
            form = null;
            done();
        });
        before.before(form);
        input.focus();
    });
}
